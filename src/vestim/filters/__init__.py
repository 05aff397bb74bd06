"""Generic filtering building blocks (Numba kernels on small dense arrays).

Modules: :mod:`~vestim.filters.kalman` (the Kalman measurement updates: one
Joseph-form update for every linear measurement, scalar or vector, and the
unscented update from sigma-point statistics), :mod:`~vestim.filters.ukf`
(the papers' unscented transform: weights, sigma points, weighted mean and
cross-covariance), :mod:`~vestim.filters.linalg` (small Cholesky helpers),
:mod:`~vestim.filters.niw` (Normal-inverse-Wishart statistics and the
multivariate Student-t of 002 Sec. III-B and IV-B),
:mod:`~vestim.filters.resampling` (weights, effective sample size,
systematic resampling). The estimators in :mod:`vestim.estimators` compose
them inside their compiled time loops (the LuGre KF/UKF corner
filters, the stiffness EKF and RLS + KF); nothing here knows about vehicles.
"""
