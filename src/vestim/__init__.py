"""vestim: corner-based estimation of tire forces and vehicle velocities robust to road friction.

Layers (imports go one way): ``io`` and ``models`` (physics) → ``filters`` →
``estimators`` → ``pipeline``; ``sim`` produces logs with ground truth.
"""

__version__ = "0.1.0"
