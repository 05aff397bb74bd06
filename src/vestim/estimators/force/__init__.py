"""Tire forces per corner without road friction: longitudinal, lateral, normal (001 Sec. III)."""

from vestim.estimators.force.estimator import ForceConfig, ForceEstimator
from vestim.estimators.registry import register

register("force", "ukf", "UKF on the wheel dynamics with the torque filtered as a state and "
         "covariance switching on high wheel acceleration", default=True,
         cite="000 eq. (10)–(12), 004 eq. (1)–(5), Sec. II-A", tables=("force_params",),
         outputs=("sigma_fx",))
register("force", "ukf_rw", "the papers' UKF exactly: x = [ω, F_x], F_x a random walk",
         cite="000 eq. (10)–(12), 004 eq. (1)–(5)", tables=("force_params",),
         outputs=("sigma_fx",))
register("force", "pid", "PID observer of the wheel dynamics", cite="001 eq. (2)–(5)",
         tables=("force_params",))
register("force", "uio", "unknown-input observer of the wheel dynamics", cite="000 eq. (2)–(3)",
         tables=("force_params",))
register("force", "naive", "finite-difference floor F_x = (T − I_w Δω/Δt)/R_e")
register("normal", "static", "load transfer with the quasi-static elastic roll moment "
         "m (h − h_rc)(f_y + f_z sin φ)", default=True,
         cite="001 eq. (15) (our corrected form of 000 eq. (14), 001 eq. (17))",
         tables=("force_params",), needs_wheel_speeds=False)
register("normal", "dynamic", "load transfer with the roll moment of the suspension states "
         "k_φ φ̂ + c_φ p", cite="001 eq. (15)–(17), 000 Sec. II-B",
         tables=("force_params",), needs_wheel_speeds=False)

__all__ = ["ForceConfig", "ForceEstimator"]
