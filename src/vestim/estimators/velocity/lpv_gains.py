"""Observer gain schedules and their TOML file (format version 1).

A gain schedule gives, per direction ("longitudinal", "lateral"), the
innovation-form gains L1(|ω|), L2(|ω|) of the corner observer
``x̂˙ = A(ω)x̂ + B u + L (μ − C(ω)x̂)`` (001 eq. (24), (38);
:mod:`vestim.models.lpv`) tabulated on a wheel-speed grid; between grid points
they are interpolated linearly, and held constant beyond the ends. A file
written by :func:`vestim.design.design_lpv` also carries the certificate the
gains were designed with, so it can be re-verified independently.

File format (all keys required unless marked optional)::

    format_version = 1
    vehicle = "hashemi_suv"            # name of the vehicle file designed for
    gain_form = "innovation"           # the only form stored (001 eq. (24))
    scheduling = "abs_omega"           # gains are functions of |ω|, rad/s

    [longitudinal]                     # and/or [lateral]; at least one
    omega = [0.0, 5.0, ...]            # rad/s, strictly increasing, >= 0
    L1 = [...]                         # m/s   (per unit normalised force)
    L2 = [...]                         # m/s²
    sigma0 = 632.1                     # tire data designed for (1/m, s/m, s/m, 1/m, m)
    sigma1 = 0.76
    sigma2 = 0.0016
    kappa = 8.32
    wheel_radius = 0.33

    [longitudinal.certificate]         # optional
    gamma = 1.02                       # certified L2 gain Ω → e_vr
    gamma_opt = 1.0                    # solver optimum before the robustness slack
    verified = true                    # certificate verified with the rational gains
    schedule_verified = true           # ... and with the tabulated, interpolated gains
    min_eig = 1e-6                     # smallest verified eigenvalue margin
    omega_max = 180.0                  # rad/s
    omega_dot_max = 800.0              # rad/s²
    pole_radius = 400.0                # 1/s (0 = none)
    P = [[[..., ...], [..., ...]], ...]    # P(ω) = Σ P[i] |ω|^i, original units
    chi = [[[...], [...]], ...]            # χ(ω) = Σ chi[i] |ω|^i; L = P⁻¹ χ

Files are written atomically (temporary file, then :func:`os.replace`).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vestim.errors import VestimError
from vestim.io.files import write_text_atomic
from vestim.models.lpv import LuGreAxis

FArray = NDArray[np.float64]

__all__ = [
    "DIRECTIONS",
    "FORMAT_VERSION",
    "GainSchedule",
    "GainsFileError",
    "ObserverGains",
    "StoredCertificate",
    "load_gains",
    "save_gains",
]

FORMAT_VERSION = 1
DIRECTIONS: tuple[str, str] = ("longitudinal", "lateral")


class GainsFileError(VestimError, ValueError):
    """A gains TOML file is invalid; the message names the table and key."""


@dataclass(frozen=True)
class StoredCertificate:
    """The certificate a schedule was designed with (see the module docstring)."""

    gamma: float
    gamma_opt: float
    verified: bool
    schedule_verified: bool
    min_eig: float
    omega_max: float
    omega_dot_max: float
    pole_radius: float | None
    lyapunov: FArray
    chi: FArray


@dataclass(frozen=True)
class ObserverGains:
    """Innovation-form gains of one direction, tabulated over |ω|.

    Attributes:
        omega: |ω| grid, rad/s, strictly increasing, ≥ 0.
        l1: L1(|ω|), m/s.  l2: L2(|ω|), m/s².
        axis: LuGre parameters the gains were designed for.
        certificate: the design certificate, if any.
    """

    omega: FArray
    l1: FArray
    l2: FArray
    axis: LuGreAxis
    certificate: StoredCertificate | None = None

    def __post_init__(self) -> None:
        w, a, b = (np.asarray(v, float) for v in (self.omega, self.l1, self.l2))
        if w.ndim != 1 or w.size < 1 or a.shape != w.shape or b.shape != w.shape:
            raise ValueError("ObserverGains: omega, L1 and L2 must be 1-D of equal length")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise ValueError("ObserverGains: omega, L1 and L2 must be finite")
        if w[0] < 0 or np.any(np.diff(w) <= 0):
            raise ValueError("ObserverGains: omega must be >= 0 and strictly increasing")

    def gains(self, omega: FArray | float) -> tuple[FArray, FArray]:
        """(L1, L2) at wheel speed(s) ω (sign ignored), linear interpolation, clamped ends."""
        w = np.abs(np.asarray(omega, float))
        return np.interp(w, self.omega, self.l1), np.interp(w, self.omega, self.l2)

    def gain_matrix(self, omega: FArray) -> FArray:
        """L(ω) as (K, 2, 1) columns, for :meth:`ObserverPlant.closed_loop`."""
        l1, l2 = self.gains(np.atleast_1d(omega))
        return np.stack([l1, l2], axis=-1)[..., None]


@dataclass(frozen=True)
class GainSchedule:
    """Gain schedules of the longitudinal and/or lateral corner observers of one vehicle."""

    vehicle: str
    directions: dict[str, ObserverGains] = field(default_factory=dict)
    omega_dot_max: float = float("nan")

    def __post_init__(self) -> None:
        unknown = sorted(set(self.directions) - set(DIRECTIONS))
        if unknown or not self.directions:
            raise ValueError(f"GainSchedule: directions must be a non-empty subset of {DIRECTIONS},"
                             f" got {sorted(self.directions)}")

    @property
    def longitudinal(self) -> ObserverGains | None:
        """Gains of the longitudinal observer (001 eq. (24)), if present."""
        return self.directions.get("longitudinal")

    @property
    def lateral(self) -> ObserverGains | None:
        """Gains of the lateral observer (001 eq. (38)), if present."""
        return self.directions.get("lateral")

    def save_gains(self, path: str | Path) -> Path:
        """Write this schedule as TOML (see the module docstring); returns the path."""
        return save_gains(self, path)

    def summary(self) -> str:
        """One line per direction: gain ranges and certified γ."""
        lines = [f"gain schedule for {self.vehicle!r}"]
        for name, g in self.directions.items():
            c = g.certificate
            cert = ("no certificate" if c is None else
                    f"gamma = {c.gamma:.4g}, verified = {c.verified}, "
                    f"schedule verified = {c.schedule_verified}")
            lines.append(f"  {name}: |omega| in [{g.omega[0]:g}, {g.omega[-1]:g}] rad/s, "
                         f"L1 in [{g.l1.min():.4g}, {g.l1.max():.4g}] m/s, "
                         f"L2 in [{g.l2.min():.4g}, {g.l2.max():.4g}] m/s^2; {cert}")
        return "\n".join(lines)


# ------------------------------------------------------------------------------ TOML
def _fmt(v: float) -> str:
    v = float(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return repr(v)


def _array(a: Iterable[Any] | FArray) -> str:
    arr = np.asarray(a, float)
    if arr.ndim == 0:
        return _fmt(float(arr))
    return "[" + ", ".join(_array(x) for x in arr) + "]"


def _dumps(schedule: GainSchedule) -> str:
    out = [
        "# vestim LPV observer gain schedule (format version 1; docs/methods.md)",
        f"format_version = {FORMAT_VERSION}",
        f"vehicle = {_quote(schedule.vehicle)}",
        'gain_form = "innovation"  # x_hat\' = A x_hat + B u + L (mu - C(omega) x_hat), 001 eq. (24)',
        'scheduling = "abs_omega"  # functions of |omega| in rad/s; linear, clamped at the ends',
        "",
    ]
    for name, g in schedule.directions.items():
        ax = g.axis
        out += [
            f"[{name}]",
            f"omega = {_array(g.omega)}  # rad/s",
            f"L1 = {_array(g.l1)}  # m/s",
            f"L2 = {_array(g.l2)}  # m/s^2",
            f"sigma0 = {_fmt(ax.sigma0)}",
            f"sigma1 = {_fmt(ax.sigma1)}",
            f"sigma2 = {_fmt(ax.sigma2)}",
            f"kappa = {_fmt(ax.kappa)}",
            f"wheel_radius = {_fmt(ax.wheel_radius)}",
            "",
        ]
        c = g.certificate
        if c is not None:
            out += [
                f"[{name}.certificate]",
                f"gamma = {_fmt(c.gamma)}",
                f"gamma_opt = {_fmt(c.gamma_opt)}",
                f"verified = {str(c.verified).lower()}",
                f"schedule_verified = {str(c.schedule_verified).lower()}",
                f"min_eig = {_fmt(c.min_eig)}",
                f"omega_max = {_fmt(c.omega_max)}",
                f"omega_dot_max = {_fmt(c.omega_dot_max)}",
                f"pole_radius = {_fmt(c.pole_radius or 0.0)}",
                f"P = {_array(c.lyapunov)}",
                f"chi = {_array(c.chi)}",
                "",
            ]
    return "\n".join(out)


def _quote(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def save_gains(schedule: GainSchedule, path: str | Path) -> Path:
    """Write ``schedule`` to ``path`` as TOML, atomically; returns the path."""
    return write_text_atomic(path, _dumps(schedule))


_TOP = {"format_version", "vehicle", "gain_form", "scheduling", *DIRECTIONS}
_DIR = {"omega", "L1", "L2", "sigma0", "sigma1", "sigma2", "kappa", "wheel_radius", "certificate"}
_CERT = {"gamma", "gamma_opt", "verified", "schedule_verified", "min_eig", "omega_max",
         "omega_dot_max", "pole_radius", "P", "chi"}


def _need(table: dict[str, Any], key: str, where: str) -> Any:
    if key not in table:
        raise GainsFileError(f"{where} {key} is missing")
    return table[key]


def _float(table: dict[str, Any], key: str, where: str) -> float:
    v = _need(table, key, where)
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise GainsFileError(f"{where} {key} = {v!r} must be a number")
    return float(v)


def _floats(table: dict[str, Any], key: str, where: str) -> FArray:
    v = _need(table, key, where)
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError) as exc:
        raise GainsFileError(f"{where} {key} must be an array of numbers") from exc
    if arr.ndim == 0 or not np.all(np.isfinite(arr)):
        raise GainsFileError(f"{where} {key} must be a non-empty array of finite numbers")
    return arr


def _unknown(table: dict[str, Any], allowed: set[str], where: str) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise GainsFileError(f"{where} has unknown key(s) {', '.join(extra)}; allowed: "
                             f"{', '.join(sorted(allowed))}")


def _direction(name: str, t: Any) -> ObserverGains:
    where = f"[{name}]"
    if not isinstance(t, dict):
        raise GainsFileError(f"{where} must be a table")
    _unknown(t, _DIR, where)
    try:
        axis = LuGreAxis(*(_float(t, k, where)
                           for k in ("sigma0", "sigma1", "sigma2", "kappa", "wheel_radius")))
    except ValueError as exc:
        if isinstance(exc, GainsFileError):
            raise
        raise GainsFileError(f"{where}: {exc}") from exc
    cert = None
    if "certificate" in t:
        c = t["certificate"]
        cw = f"[{name}.certificate]"
        if not isinstance(c, dict):
            raise GainsFileError(f"{cw} must be a table")
        _unknown(c, _CERT, cw)
        flags = {}
        for k in ("verified", "schedule_verified"):
            v = _need(c, k, cw)
            if not isinstance(v, bool):
                raise GainsFileError(f"{cw} {k} = {v!r} must be true or false")
            flags[k] = v
        p = _floats(c, "P", cw)
        chi = _floats(c, "chi", cw)
        if p.ndim != 3 or p.shape[1:] != (2, 2) or chi.shape != (p.shape[0], 2, 1):
            raise GainsFileError(f"{cw} P must have shape (f+1, 2, 2) and chi (f+1, 2, 1), "
                                 f"got {p.shape} and {chi.shape}")
        radius = _float(c, "pole_radius", cw)
        cert = StoredCertificate(
            gamma=_float(c, "gamma", cw), gamma_opt=_float(c, "gamma_opt", cw),
            verified=flags["verified"], schedule_verified=flags["schedule_verified"],
            min_eig=_float(c, "min_eig", cw), omega_max=_float(c, "omega_max", cw),
            omega_dot_max=_float(c, "omega_dot_max", cw),
            pole_radius=radius if radius > 0 else None, lyapunov=p, chi=chi)
    try:
        return ObserverGains(_floats(t, "omega", where), _floats(t, "L1", where),
                             _floats(t, "L2", where), axis, cert)
    except ValueError as exc:
        if isinstance(exc, GainsFileError):
            raise
        raise GainsFileError(f"{where}: {exc}") from exc


def load_gains(path: str | Path) -> GainSchedule:
    """Read a gains TOML file (see the module docstring).

    Raises:
        GainsFileError: unreadable file, TOML syntax error, or invalid content
            (the message names the file, table and key).
    """
    p = Path(path)
    if not p.is_file():
        raise GainsFileError(f"gains file {str(p)!r} not found")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise GainsFileError(f"{p}: not valid TOML: {exc}") from exc
    try:
        _unknown(data, _TOP, "top level")
        version = _need(data, "format_version", "top level")
        if version != FORMAT_VERSION:
            raise GainsFileError(f"format_version = {version!r}; this vestim reads version "
                                 f"{FORMAT_VERSION}")
        for key, want in (("gain_form", "innovation"), ("scheduling", "abs_omega")):
            if _need(data, key, "top level") != want:
                raise GainsFileError(f"{key} = {data[key]!r}; only {want!r} is supported")
        vehicle = _need(data, "vehicle", "top level")
        if not isinstance(vehicle, str):
            raise GainsFileError(f"vehicle = {vehicle!r} must be a string")
        dirs = {d: _direction(d, data[d]) for d in DIRECTIONS if d in data}
        if not dirs:
            raise GainsFileError("no [longitudinal] or [lateral] table")
    except GainsFileError as exc:
        raise GainsFileError(f"{p}: {exc}") from None
    rates = [g.certificate.omega_dot_max for g in dirs.values() if g.certificate is not None]
    return GainSchedule(vehicle=vehicle, directions=dirs,
                        omega_dot_max=max(rates) if rates else float("nan"))
