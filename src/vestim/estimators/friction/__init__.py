"""Road friction potential under each tire, where the tire uses enough of it to tell."""

from vestim.estimators.friction.potential import (
    FrictionKernelParams,
    FrictionParams,
    FrictionState,
    corner_kx,
    friction_kernel,
    friction_params,
    friction_potential,
    friction_step,
    invert_shape,
    new_friction_state,
)

__all__ = ["FrictionKernelParams", "FrictionParams", "FrictionState", "corner_kx",
           "friction_kernel", "friction_params", "friction_potential", "friction_step",
           "invert_shape", "new_friction_state"]
