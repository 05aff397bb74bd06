"""Estimators: vehicle-level compositions of :mod:`vestim.models` and :mod:`vestim.filters`.

Each subpackage validates its inputs, packs parameters and runs a compiled
kernel; e.g. :mod:`vestim.estimators.stiffness` (002, tire stiffness and
vehicle state).
"""
