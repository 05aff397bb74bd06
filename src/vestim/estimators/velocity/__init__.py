"""Velocity estimators: reference-speed filter, kinematic baseline, tire-model corner observers."""

from vestim.estimators.registry import register

register("velocity", "fused", "the reference filter with the LuGre KF corner estimates as "
         "extra CG-speed measurements while at least three wheels slip",
         cite="001 Fig. 1, 000 eq. (16)–(23) (ours: the composition)",
         tables=("reference", "cornering", "radius", "corner", "fusion_params"),
         needs_wheel_speeds=False, corner="lugre_kf", outputs=("sigma_v", "bias_ax"))
register("velocity", "reference", "ABS/ESC-style reference-speed filter: a_x, a_y integrated, "
         "wheel speeds and linear-tire slip-angle bounds as measurements", default=True,
         tables=("reference", "cornering", "radius"), needs_wheel_speeds=False,
         outputs=("sigma_v", "bias_ax"))
register("velocity", "kinematic", "kinematic integration of the accelerometers, reset at "
         "free rolling", cite="000 eq. (15)")
register("velocity", "kf", "LuGre corner Kalman filter per wheel, fused to the CG",
         cite="000 eq. (16)–(23)", tables=("reference", "corner", "fusion_params"),
         corner="lugre_kf", outputs=("bias_ax",))
register("velocity", "ukf", "LuGre corner UKF per wheel, fused to the CG", cite="003 Alg. 1",
         tables=("reference", "corner", "fusion_params"), corner="lugre_ukf",
         outputs=("bias_ax",))
register("velocity", "lpv", "LPV corner observer per wheel (gains from `vestim design lpv` "
         "or 001's), fused to the CG", cite="001 eq. (22)–(24), (36)–(38)",
         tables=("reference", "fusion_params"), corner="lpv", outputs=("bias_ax",))
