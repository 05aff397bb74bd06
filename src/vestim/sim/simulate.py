"""Run a maneuver on the plant and return a spec log with measured and ``ref_`` channels."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pandas as pd

from vestim.constants import G
from vestim.io.vehicle import Vehicle, load_vehicle
from vestim.models.tire import lugre_theta_for_mu
from vestim.sim import plant as P  # noqa: N812  (P.X reads as "plant layout")
from vestim.sim.maneuvers import Maneuver, get_maneuver
from vestim.sim.sensors import SensorModel

SIM_RATE = 1000.0
"""Default integration rate, Hz (fixed-step RK4)."""

EXTRA_COLUMNS = ("x", "y", "yaw", "distance", "grade", "bank")
"""Recorded plant channels outside the spec (trajectory, road); dropped unless ``extras=True``."""


def ackermann(delta: np.ndarray, wheelbase: float, track: float) -> tuple[np.ndarray, np.ndarray]:
    """Left and right road-wheel angles (rad) of ideal Ackermann geometry for a mean angle ``delta``.

    cot δ_outer − cot δ_inner = t/L; written as tan δ_fl = L tan δ / (L − (t/2) tan δ)
    (and + for fr) so that it holds for both turning directions and δ = 0.
    """
    tan_d = np.tan(delta)
    fl = np.arctan(wheelbase * tan_d / (wheelbase - 0.5 * track * tan_d))
    fr = np.arctan(wheelbase * tan_d / (wheelbase + 0.5 * track * tan_d))
    return fl, fr


def plant_parameters(vehicle: Vehicle, maneuver: Maneuver) -> np.ndarray:
    """Pack the vehicle file and maneuver options into the kernel's parameter vector."""
    b, s, a, pt, t, mf = (vehicle.body, vehicle.suspension, vehicle.aerodynamics,
                          vehicle.powertrain, vehicle.tire, vehicle.magic_formula)
    drivetrain = maneuver.drivetrain or b.drivetrain
    front_drive = {"awd": pt.front_drive_share, "fwd": 1.0, "rwd": 0.0}[drivetrain]
    p = np.zeros(P.N_PARAM)
    values = {
        P.P_M: b.mass, P.P_IZ: b.yaw_inertia, P.P_IW: b.wheel_inertia, P.P_LF: b.lf,
        P.P_LR: b.lr, P.P_TF: b.track_f, P.P_TR: b.track_r, P.P_H: b.cg_height,
        P.P_HRC: b.roll_center_height, P.P_R: b.wheel_radius, P.P_IPHI: s.roll_inertia,
        P.P_ITH: s.pitch_inertia, P.P_KPHI: s.roll_stiffness, P.P_CPHI: s.roll_damping,
        P.P_KTH: s.pitch_stiffness, P.P_CTH: s.pitch_damping, P.P_SF: s.roll_stiffness_front_share,
        P.P_HPC: s.pitch_center_height, P.P_DRAG: 0.5 * a.air_density * a.drag_area,
        P.P_FRR: a.rolling_resistance,
        P.P_TIRE: P.TIRE_LUGRE if maneuver.tire == "lugre" else P.TIRE_MAGIC,
        P.P_TAU_LAG: 0.005,
        P.P_S0X: t.sigma0_x, P.P_S1X: t.sigma1_x, P.P_S2X: t.sigma2_x, P.P_KAX: t.kappa_x,
        P.P_S0Y: t.sigma0_y, P.P_S1Y: t.sigma1_y, P.P_S2Y: t.sigma2_y, P.P_KAY: t.kappa_y,
        P.P_MUS: t.mu_s, P.P_MUC: t.mu_c, P.P_VS: t.v_s, P.P_ALPHA: t.alpha,
        P.P_FZ0: mf.fz0, P.P_CX: mf.c_x, P.P_EX: mf.e_x, P.P_KX: mf.kx, P.P_KXL: mf.kx_load,
        P.P_CY: mf.c_y, P.P_EY: mf.e_y, P.P_KY1: mf.ky1, P.P_KY2: mf.ky2, P.P_RBX1: mf.rbx1,
        P.P_RBX2: mf.rbx2, P.P_RBY1: mf.rby1, P.P_RBY2: mf.rby2, P.P_RELX: mf.relax_x,
        P.P_RELY: mf.relax_y, P.P_DAMPX: mf.damping_x, P.P_DAMPY: mf.damping_y,
        P.P_TDMAX: pt.max_drive_torque, P.P_PMAX: pt.max_power, P.P_FRONT_DRIVE: front_drive,
        P.P_TBMAX: pt.max_brake_torque, P.P_FRONT_BRAKE: pt.brake_front_share,
        P.P_VMAX: pt.max_speed,
        P.P_TC: float(maneuver.tc), P.P_ABS: float(maneuver.abs_),
        P.P_KP_SPEED: 0.5, P.P_KI_SPEED: 0.2,
    }
    for index, value in values.items():
        p[index] = value
    return p


def _theta_table(vehicle: Vehicle, maneuver: Maneuver) -> tuple[np.ndarray, np.ndarray]:
    """θ(μ) of the LuGre plant on a grid covering the road's μ (see lugre_theta_for_mu)."""
    mus = np.unique(np.asarray(maneuver.road.mu, dtype=float))
    grid = np.unique(np.concatenate([mus, np.linspace(mus.min(), mus.max(), 12)]))
    if maneuver.tire != "lugre":
        return grid, np.ones_like(grid)
    return grid, np.array([lugre_theta_for_mu(m, vehicle.tire) for m in grid])


def kernel_params(vehicle: Vehicle, maneuver: Maneuver, dt: float, stride: int,
                  roll_scale: float = 1.0) -> P.PlantParams:
    """Everything :func:`~vestim.sim.plant.simulate_kernel` holds fixed over a run.

    Args:
        vehicle, maneuver: the run.
        dt: integration step (s). stride: integration steps per recorded row.
        roll_scale: the roll stiffness and damping of the plant are the vehicle's divided by
            this (see :func:`simulate`).
    """
    if not (math.isfinite(roll_scale) and roll_scale > 0):
        raise ValueError(f"roll_scale = {roll_scale} must be > 0")
    p = plant_parameters(vehicle, maneuver)
    p[P.P_KPHI] /= roll_scale
    p[P.P_CPHI] /= roll_scale
    body = vehicle.body
    road = maneuver.road
    theta_mu, theta_val = _theta_table(vehicle, maneuver)
    return P.PlantParams(
        p=p, xw=np.array([body.lf, body.lf, -body.lr, -body.lr]),
        yw=np.array([body.track_f, -body.track_f, body.track_r, -body.track_r]) * 0.5,
        dt=dt, stride=stride,
        road=P.RoadTables(knots=np.asarray(road.knots, float), mu=np.asarray(road.mu, float),
                          scale=np.asarray(road.stiffness, float), by_distance=road.by_distance,
                          geo_knots=np.asarray(road.geo_knots, float),
                          grade=np.asarray(road.grade, float), bank=np.asarray(road.bank, float)),
        theta_mu=theta_mu, theta_val=theta_val)


def initial_state(vehicle: Vehicle, maneuver: Maneuver) -> np.ndarray:
    """Straight driving at v0 with free-rolling wheels, body at rest relative to the road."""
    x0 = np.zeros(P.N_STATE)
    x0[P.VX] = maneuver.v0
    x0[P.OMEGA:P.OMEGA + 4] = maneuver.v0 / vehicle.body.wheel_radius
    road = maneuver.road
    grade = float(np.interp(0.0, road.geo_knots, road.grade))
    bank = float(np.interp(0.0, road.geo_knots, road.bank))
    x0[P.FX_LAG] = G * math.sin(grade)
    x0[P.FY_LAG] = G * math.sin(bank) * math.cos(grade)
    return x0


def simulate(
    maneuver: Maneuver | str,
    vehicle: Vehicle | str = "hashemi_suv",
    *,
    seed: int = 0,
    sensors: SensorModel | None = None,
    sim_rate: float = SIM_RATE,
    extras: bool = False,
    progress: Callable[[float], None] | None = None,
    roll_scale: float = 1.0,
) -> pd.DataFrame:
    """Simulate a maneuver and return a log in the spec's format.

    Args:
        maneuver: a :class:`Maneuver` or a library name (with its defaults).
        vehicle: a :class:`Vehicle`, a TOML path or a built-in name.
        seed: seeds the sensor noise and biases; the same seed gives the same log bit for bit.
        sensors: sampling rate and noise model (default: :class:`SensorModel`, 200 Hz).
        sim_rate: integration rate in Hz; must be an integer multiple of the sensor rate.
        extras: also return the trajectory and road channels of :data:`EXTRA_COLUMNS`.
        progress: called with the completed fraction in [0, 1] after each chunk.
        roll_scale: the plant's roll stiffness and damping are the vehicle's divided by this
            (its roll gradient × ``roll_scale``), while the log is estimated with the vehicle
            file as it is: a plant that does not roll as the estimator's file says (a real
            car's), which the default (1) hides.

    Returns:
        DataFrame with ``t``, every measured channel (noisy), ``steering_wheel_angle``,
        every ``ref_`` channel (exact) and ``ref_stiffness_*``. ``df.attrs`` holds
        the run's metadata (maneuver, vehicle, tire, drivetrain, seed).
    """
    m = get_maneuver(maneuver) if isinstance(maneuver, str) else maneuver
    veh = load_vehicle(vehicle) if isinstance(vehicle, str) else vehicle
    sensors = sensors or SensorModel()
    stride_f = sim_rate / sensors.rate
    stride = round(stride_f)
    if stride < 1 or abs(stride - stride_f) > 1e-9:
        raise ValueError(f"sim_rate {sim_rate} Hz must be an integer multiple of the sensor "
                         f"rate {sensors.rate} Hz")
    if sim_rate < 1000.0:
        raise ValueError(f"sim_rate {sim_rate} Hz is below the 1 kHz the plant needs")
    dt = 1.0 / sim_rate
    n_steps = round(m.duration * sim_rate) + 1
    t = np.arange(n_steps) * dt
    body = veh.body
    swa = np.asarray(m.steering_wheel_angle(t), dtype=float)
    d_fl, d_fr = ackermann(swa / body.steering_ratio, body.wheelbase, body.track_f)
    throttle = np.clip(np.asarray(m.throttle(t), dtype=float), 0.0, 1.0)
    brake = np.clip(np.asarray(m.brake(t), dtype=float), 0.0, 1.0)
    v_target = np.asarray(m.speed(t), dtype=float)

    prm = kernel_params(veh, m, dt, stride, roll_scale)
    st = P.PlantState(x=initial_state(veh, m), ctrl=np.array([1.0] * 8 + [0.0]))

    chunk = stride * max(1, int(2.0 * sensors.rate))  # two seconds of samples per call
    pieces = []
    for k0 in range(0, n_steps, chunk):
        k1 = min(k0 + chunk, n_steps)
        inp = P.DriverInputs(delta_fl=d_fl[k0:k1], delta_fr=d_fr[k0:k1], throttle=throttle[k0:k1],
                             brake=brake[k0:k1], v_target=v_target[k0:k1])
        pieces.append(P.simulate_kernel(prm, st, inp, k0))
        if not np.all(np.isfinite(st.x)):
            raise FloatingPointError(f"plant diverged near t = {k1 * dt:.3f} s in {m.name!r}")
        if progress is not None:
            progress(k1 / n_steps)
    rec = np.concatenate(pieces)
    log = pd.DataFrame(rec, columns=list(P.REC_NAMES))
    log.insert(list(log.columns).index("delta_fr") + 1, "steering_wheel_angle", swa[::stride])
    log = sensors.apply(log, body.steering_ratio, np.random.default_rng(seed))
    if not extras:
        log = log.drop(columns=list(EXTRA_COLUMNS))
    log.attrs.update({
        "maneuver": m.name, "description": m.description, "vehicle": veh.name, "tire": m.tire,
        "drivetrain": m.drivetrain or body.drivetrain, "tc": str(m.tc), "abs": str(m.abs_),
        "seed": str(seed), "sensor_rate": str(sensors.rate), "sim_rate": str(sim_rate),
        "roll_scale": str(roll_scale),
    })
    return log
