"""Road friction potential under each tire, where the tire uses enough of it to tell."""

from vestim.estimators.friction.potential import (
    FrictionParams,
    corner_kx,
    friction_kernel,
    friction_params,
    friction_potential,
    invert_shape,
)

__all__ = ["FrictionParams", "corner_kx", "friction_kernel", "friction_params", "friction_potential",
           "invert_shape"]
