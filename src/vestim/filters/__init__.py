"""Generic filtering building blocks (Numba kernels on small dense arrays).

Modules: :mod:`~vestim.filters.linalg` (small Cholesky helpers),
:mod:`~vestim.filters.niw` (Normal-inverse-Wishart statistics and the
multivariate Student-t of 002 Sec. III-B and IV-B),
:mod:`~vestim.filters.resampling` (weights, effective sample size,
systematic resampling), :mod:`~vestim.filters.ukf` (unscented transform).
The estimators in :mod:`vestim.estimators` compose them inside their compiled
time loops; nothing here knows about vehicles.
"""
