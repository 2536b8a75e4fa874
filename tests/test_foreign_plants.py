"""The foreign-plant fixture of issue 10: ForeignBallScrew and ForeignZStage, hand-written
FMI 3.0 co-simulation FMUs in fmus/foreign/ (other names, units and physics than the
project's plants). Driven open loop (or with a loop written here on TRUE outputs, to set
a speed or feed) through fmpy; every expectation is derived here from the parameters and the
equations of fmus/foreign/*/README.md, not read from the FMU."""
import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from drillcosim.fmus.foreign.build import FOREIGN, HERE, fmu_path

try:
    from plant_helpers import ExtractedPlant, plant_maker
except ImportError:  # tests/ imported as a package
    from tests.plant_helpers import ExtractedPlant, plant_maker

# data of the true plants (the FMUs' start values; test_start_values_match_xml pins them)
BS = dict(Jm=2.0e-4, m_table=40.0, lead=4.0e-3, k_screw=130e6, d_screw=4000.0, Kt=0.87,
          T_coul=0.045, T_stat=0.075, w_strb=0.6, strb_exp=1.5, b_visc=8e-4,
          k_contact=20e6, d_contact=3000.0)
BS["p"] = BS["lead"] / (2 * np.pi)                      # m/rad
BS["J_t"] = BS["m_table"] * BS["p"] ** 2                # table reflected to the motor, kg m2
BS["J_tot"] = BS["Jm"] + BS["J_t"]
ZS = dict(mass=4.3, Kf=24.6, g=9.81, F_bal=38.0, F_coul=6.0, F_stat=9.5, v_strb=3e-3, strb_exp=1.5,
          c_visc=45.0, k_contact=20e6, d_contact=300.0)
LAW = dict(K_cfrp=6900.0, K_ti=17300.0, K_al=1150.0, x=0.8)


class Plant(ExtractedPlant):
    """One instance of a foreign FMU through fmpy's FMU3Slave, by variable name."""

    def __init__(self, name, params=None):
        path = str(fmu_path(name))
        self.md = read_model_description(path)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.messages = []
        self._dir = extract(path)
        self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(logMessage=lambda env, st, cat, msg: self.messages.append(msg.decode()))
        try:
            self.fmu.enterInitializationMode(startTime=0.0)
            for k, v in (params or {}).items():
                self.set(k, v)
            self.fmu.exitInitializationMode()
        except Exception:
            self.fmu.freeInstance()
            shutil.rmtree(self._dir, ignore_errors=True)
            raise
        self.t = 0.0

    def set(self, name, x):
        v = self.vars[name]
        if v.type == "Int32":
            self.fmu.setInt32([v.valueReference], [int(x)])
        else:
            self.fmu.setFloat64([v.valueReference], [float(x)])

    def get(self, *names):
        return np.array(self.fmu.getFloat64([self.vars[n].valueReference for n in names]))


@pytest.fixture
def plants():
    yield from plant_maker(Plant)


AIR_BS = {"surface_pos": 500.0}      # stack far away: air moves
AIR_ZS = {"surface_pos": 500.0}


def feed_loop_bs(v_feed, bw_hz=20.0, dt=5e-4):
    """PID on the true motor angle: the table follows v_feed [m/s] (a very stiff feed)."""
    w = 2 * np.pi * bw_hz
    J, p = BS["J_tot"], BS["p"]
    kp, kd, ki = 3 * w * w * J, 3 * w * J, w ** 3 * J
    st = {"i": 0.0}

    def control(pl):
        th_deg, w_rpm = pl.get("motor_angle", "motor_vel")
        e = v_feed * pl.t / p - np.radians(th_deg)
        st["i"] += e * dt
        tau = kp * e + kd * (v_feed / p - w_rpm * np.pi / 30) + ki * st["i"]
        pl.set("iq_ref", 1e3 * tau / BS["Kt"])
    return control


def feed_loop_zs(v_feed, bw_hz=30.0, dt=2e-4):
    """PID on the true stage position (um) with gravity feed-forward: z follows v_feed [m/s]."""
    w = 2 * np.pi * bw_hz
    m = ZS["mass"]
    kp, kd, ki = 3 * w * w * m, 3 * w * m, w ** 3 * m
    bias = m * ZS["g"] - ZS["F_bal"]
    st = {"i": 0.0}

    def control(pl):
        z_um, v_mms = pl.get("tip_pos", "stage_vel")
        e = v_feed * pl.t - z_um * 1e-6
        st["i"] += e * dt
        F = kp * e + kd * (v_feed - v_mms * 1e-3) + ki * st["i"] - bias
        pl.set("iq_cmd", 1e3 * F / ZS["Kf"])
    return control


# ------------------------------------------------------------------ FMU conformance

@pytest.mark.parametrize("name", FOREIGN)
def test_validate_and_no_project_code(name):
    assert validate_fmu(str(fmu_path(name))) == []
    # written apart from fmus/common: only the C library, the FMI headers and its own files
    allowed = {"math.h", "string.h", "stdarg.h", "stdio.h", "stdlib.h", "stdint.h", "stddef.h",
               "fmi3Functions.h", "fglue.h", "cut.h", "stribeck.h"}
    for src in [HERE / name / f"{name}.c", HERE / "fglue.c", HERE / "cut.c", HERE / "fglue.h", HERE / "cut.h", HERE / "stribeck.h"]:
        for line in src.read_text().splitlines():
            if line.startswith("#include"):
                assert line.split()[1].strip('<>"') in allowed, (src, line)
    md = read_model_description(str(fmu_path(name)))
    assert md.fmiVersion == "3.0" and md.coSimulation is not None
    assert not any(v.description and v.description.startswith("Scoring only:") for v in md.modelVariables)


@pytest.mark.parametrize("name", FOREIGN)
def test_start_values_match_xml(name, plants):
    """The hand-written XML and the C variable table agree: every start value in the XML is
    what the FMU reports before anything is set."""
    p = plants(name)
    root = ET.parse(HERE / name / "modelDescription.xml").getroot()
    n = 0
    for el in root.find("ModelVariables"):
        if el.get("start") is None:
            continue
        vr = int(el.get("valueReference"))
        got = (p.fmu.getInt32([vr])[0] if el.tag == "Int32" else p.fmu.getFloat64([vr])[0])
        assert got == pytest.approx(float(el.get("start")), rel=1e-12), el.get("name")
        n += 1
    assert n > 40


def test_master_loads_them():
    from drillcosim.cosim.fmi.slave import load_model
    for name, unit in (("ForeignBallScrew", {"scale_pos": "mm", "motor_angle": "deg", "orbit_f": "Hz"}),
                       ("ForeignZStage", {"z_meas": "um", "iq_cmd": "mA"})):
        m = load_model(fmu_path(name))
        assert m.is_fmi3
        for var, u in unit.items():
            assert m.variables[var].unit == u


# ------------------------------------------------------------------ ForeignBallScrew drive

def test_bs_two_mass_resonance(plants):
    """Current step in air: the motor-table relative velocity rings at
    sqrt(k_rot (1/Jm + 1/J_t)) / 2 pi, k_rot = k_screw p^2, J_t = m_table p^2 (298.3 Hz).
    Zero crossings over ~6 periods at 50 kHz sampling resolve the period to << 1 %; the
    screw damping (zeta ~ 0.03) shifts the damped frequency by 0.05 %: 1 % tolerance."""
    p = plants("ForeignBallScrew", AIR_BS)
    p.set("iq_ref", 500.0)
    dt = 2e-5
    o = p.run(1500, dt, ["motor_vel", "table_vel"])
    rel = o[:, 0] * np.pi / 30 * BS["p"] - o[:, 1] * 1e-3
    x = rel[250:] - np.mean(rel[250:])
    t = dt * np.arange(len(x))
    zc = np.where(np.diff(np.sign(x)) != 0)[0]
    tz = t[zc] - x[zc] * dt / (x[zc + 1] - x[zc])
    f_meas = 1.0 / (2 * np.mean(np.diff(tz[:12])))
    f_theory = np.sqrt(BS["k_screw"] * BS["p"] ** 2 * (1 / BS["Jm"] + 1 / BS["J_t"])) / (2 * np.pi)
    assert 250 < f_theory < 350
    assert f_meas == pytest.approx(f_theory, rel=0.01)


def test_bs_free_acceleration(plants):
    """i = 1 A in air: mean dw/dt over 20-60 ms = (Kt i - T_coul - b mean(w)) / (Jm + m p^2).
    The window spans ~25 ripple periods (ripple torque < 1 % of Kt i, averaging out) and the
    Stribeck term is e^-(100/0.6)^1.5 = 0: 1 % tolerance."""
    p = plants("ForeignBallScrew", AIR_BS)
    p.set("iq_ref", 1000.0)
    dt = 1e-4
    w = p.run(600, dt, ["motor_vel"])[:, 0] * np.pi / 30
    a, b = 200, 599
    alpha = (w[b] - w[a]) / ((b - a) * dt)
    expected = (BS["Kt"] * 1.0 - BS["T_coul"] - BS["b_visc"] * np.mean(w[a:b + 1])) / BS["J_tot"]
    assert alpha == pytest.approx(expected, rel=0.01)


def test_bs_encoder_quantisation(plants):
    p = plants("ForeignBallScrew", AIR_BS)
    p.set("iq_ref", 300.0)
    o = p.run(300, 1e-4, ["motor_angle", "scale_pos", "tip_pos"])
    counts = o[:, 0] / (360.0 / 65536)
    assert np.allclose(counts, np.round(counts), atol=1e-6)
    assert len(np.unique(o[:, 0])) > 100
    um = o[:, 1] * 1e3
    assert np.allclose(um, np.round(um), atol=1e-6)
    lag = o[:, 2] - o[:, 1]
    assert np.all(lag >= -1e-9) and np.all(lag < 1e-3 + 1e-9)        # floor to 1 um


@pytest.mark.parametrize("w", [0.2, 0.6, 2.0])
def test_bs_stribeck_curve(plants, w):
    """Air cut at constant motor speed (PI loop on the true speed, ripple off): the mean
    torque Kt*mean(iq_meas) is the friction T_coul + (T_stat - T_coul) exp(-(w/w_strb)^1.5)
    + b w. 0.4 s of 15 mA noise averages to 0.3 mA (0.3 mN m); the loop's residual speed
    error is < 0.5 %: 2 % tolerance on friction of 0.05-0.07 N m."""
    p = plants("ForeignBallScrew", {**AIR_BS, "ripA": 0.0, "ripB": 0.0})
    J = BS["J_tot"]
    # speed-loop bandwidth: its gain wc J = 0.08 N m s/rad must beat the Stribeck branch's
    # negative slope (up to 0.035 N m s/rad here), else the loop limit-cycles (stick-slip)
    wc = 2 * np.pi * 60
    dt = 2e-4
    st = {"i": 0.0}

    def control(pl):
        e = w - pl.get("motor_vel")[0] * np.pi / 30
        st["i"] += e * dt
        tau = wc * J * e + wc * wc / 4 * J * st["i"] + BS["T_coul"]
        pl.set("iq_ref", 1e3 * tau / BS["Kt"])
    o = p.run(6000, dt, ["iq_meas", "motor_vel"], control)
    tail = o[4000:]
    assert np.mean(tail[:, 1]) * np.pi / 30 == pytest.approx(w, rel=0.005)
    tau_meas = BS["Kt"] * np.mean(tail[:, 0]) * 1e-3
    expected = (BS["T_coul"] + (BS["T_stat"] - BS["T_coul"]) * np.exp(-(w / BS["w_strb"]) ** BS["strb_exp"])
                + BS["b_visc"] * w)
    assert tau_meas == pytest.approx(expected, rel=0.02)


def test_bs_torque_ripple_harmonics(plants):
    """Constant current with strong viscous damping (b = 0.01) settles at w0 ~ 20 rad/s; the
    speed ripple over motor angle has lines at 4/rev and 9/rev of amplitude
    a_k / |b + j J_tot k w0| (first-order response, far below the 298 Hz resonance) and none
    at the project plant's 6/rev. 10 % tolerance (w0 varies by the ripple itself)."""
    b = 0.01
    p = plants("ForeignBallScrew", {**AIR_BS, "b_visc": b})
    i = 0.2816
    p.set("iq_ref", i * 1e3)
    dt = 2e-4
    p.run(1500, dt, ["motor_vel"])                       # settle (J/b = 22 ms)
    o = p.run(5000, dt, ["motor_angle", "motor_vel"])
    th = np.unwrap(np.radians(o[:, 0]))
    w = o[:, 1] * np.pi / 30
    w0 = np.mean(w)
    revs = int((th[-1] - th[0]) / (2 * np.pi))
    grid = th[0] + np.linspace(0, revs * 2 * np.pi, revs * 256, endpoint=False)
    spec = 2 * np.abs(np.fft.rfft(np.interp(grid, th, w))) / len(grid)
    line = lambda k: spec[k * revs]                     # noqa: E731  (k per revolution)
    for k, a in ((4, 0.006), (9, 0.003)):
        assert line(k) == pytest.approx(a / abs(b + 1j * BS["J_tot"] * k * w0), rel=0.10)
    assert line(6) < 0.05 * line(4)


# ------------------------------------------------------------------ drill and stack (ball screw)

@pytest.mark.parametrize("mat,K,rpm,feed", [(1, LAW["K_cfrp"], 2000, 0.2e-3),
                                            (2, LAW["K_ti"], 1000, 0.15e-3),
                                            (3, LAW["K_al"], 2000, 0.2e-3)])
def test_bs_thrust_law(plants, mat, K, rpm, feed):
    """Feed at a constant rate through one thick layer: steady thrust = K (f_rev/1 mm)^0.8
    (CFRP 115 N at 12 mm/min, 2000 rpm; Ti 399 N at 9 mm/min, 1000 rpm). The contact's
    relaxation time x e/v is 23 ms (CFRP) to 0.1 s (Ti at 1000 rpm): 1.3 s after entry the
    residue is < 0.5 %; 1 %."""
    p = plants("ForeignBallScrew", {"n_layers": 1, "mat1": mat, "t1": 10.0, "surface_pos": 0.02,
                                    "orb_r1": 0.0, "orb_r2": 0.0})
    p.set("spindle_n", rpm)
    dt = 5e-4
    o = p.run(4000, dt, ["thrust_force", "material_id"], feed_loop_bs(feed, dt=dt))
    f_rev_mm = feed * 1e3 * 60 / rpm
    assert np.mean(o[-600:, 0]) == pytest.approx(K * f_rev_mm ** LAW["x"], rel=0.01)
    assert o[-1, 1] == mat


def test_bs_exit_pushout_is_quadratic(plants):
    """Feed out of the last layer: within exit_t = 0.5 mm of the bottom the thrust falls as
    (remaining thickness)^2. The remaining thickness under the front is bottom - tip + F/k
    (the contact deflection). A log-log fit over r = 0.1..0.45 mm: exponent 2 +- 0.1 (the
    contact lags the shrinking coefficient by 17 um of travel)."""
    p = plants("ForeignBallScrew", {"n_layers": 1, "mat1": 1, "t1": 1.0, "surface_pos": 0.02,
                                    "orb_r1": 0.0, "orb_r2": 0.0})
    dt = 5e-4
    o = p.run(5000, dt, ["thrust_force", "tip_pos"], feed_loop_bs(0.5e-3, dt=dt))
    F, tip = o[:, 0], o[:, 1] * 1e-3
    r = 1.02e-3 - tip + F / BS["k_contact"]
    sel = (r > 0.1e-3) & (r < 0.45e-3) & (F > 0)
    slope = np.polyfit(np.log(r[sel]), np.log(F[sel]), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.1)
    assert F[-1] == 0.0                                   # through


def contact_ring(p, cur_var, F_var, n, dt):
    o = p.run(n, dt, [F_var])[:, 0]
    return o


def damped_fit(t, y):
    from scipy.optimize import curve_fit
    y0 = y - y[-len(y) // 4:].mean()
    zc = np.where(np.diff(np.sign(y0)) != 0)[0]
    f0 = 1.0 / (2 * np.mean(np.diff(t[zc])))
    model = lambda t, A, s, f, ph, c: A * np.exp(-s * t) * np.sin(2 * np.pi * f * t + ph) + c  # noqa: E731
    popt, _ = curve_fit(model, t, y, p0=[np.ptp(y) / 2, 5.0, f0, 0.0, np.mean(y)], maxfev=20000)
    A, s, f, ph, c = popt
    wd = 2 * np.pi * f
    zeta = s / np.hypot(s, wd)
    return np.hypot(s, wd) / (2 * np.pi), zeta


def test_bs_contact_lightly_damped(plants):
    """Spindle stopped (the stack is a wall), the tip at rest on a pre-drilled front 0.05 mm
    into the stack (no impact, the contact never opens), friction off: a current
    step rings the contact. Expected: the lowest mode of motor (Jm/p^2) + table on screw spring
    and contact spring with dampers d_screw, b_visc/p^2, d_contact (eigenvalues here);
    frequency within 2 %, damping ratio within 15 % and < 0.1 (lightly damped)."""
    p = plants("ForeignBallScrew", {"surface_pos": -0.05, "T_coul": 0.0, "T_stat": 0.0, "orb_r1": 0.0,
                                    "orb_r2": 0.0})
    p.set("spindle_n", 0.0)
    p.set("iq_ref", 300.0)
    dt = 2e-4
    F = p.run(1000, dt, ["thrust_force"])[:, 0]
    t = dt * np.arange(1, 1001)
    f, zeta = damped_fit(t[50:], F[50:])
    pp = BS["p"]
    M = np.diag([BS["Jm"] / pp ** 2, BS["m_table"]])
    Kmat = np.array([[BS["k_screw"], -BS["k_screw"]], [-BS["k_screw"], BS["k_screw"] + BS["k_contact"]]])
    C = np.array([[BS["d_screw"] + BS["b_visc"] / pp ** 2, -BS["d_screw"]],
                  [-BS["d_screw"], BS["d_screw"] + BS["d_contact"]]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, Kmat), -np.linalg.solve(M, C)]])
    lam = min((l for l in np.linalg.eigvals(A) if l.imag > 0), key=lambda l: abs(l))
    assert f == pytest.approx(abs(lam) / (2 * np.pi), rel=0.02)
    assert zeta == pytest.approx(-lam.real / abs(lam), rel=0.15)
    assert zeta < 0.1


def test_bs_orbital_ripple_lines(plants):
    """While cutting CFRP, thrust_ripple has lines at orbit_f and 2 orbit_f of
    orb_r1 and orb_r2 times the DC thrust (5 % tolerance: the contact force carries a small
    response to the ripple itself)."""
    p = plants("ForeignBallScrew", {"n_layers": 1, "mat1": 1, "t1": 10.0, "surface_pos": 0.02})
    p.set("orbit_f", 5.0)
    dt = 5e-4
    o = p.run(4000, dt, ["thrust_ripple", "thrust_force"], feed_loop_bs(0.2e-3, dt=dt))
    seg = o[-2000:]                                       # 1 s = 5 orbital periods
    spec = 2 * np.abs(np.fft.rfft(seg[:, 0])) / len(seg)
    F_dc = np.mean(seg[:, 1])
    assert spec[5] == pytest.approx(0.12 * F_dc, rel=0.05)
    assert spec[10] == pytest.approx(0.04 * F_dc, rel=0.05)


# ------------------------------------------------------------------ determinism and refusal

@pytest.mark.parametrize("name,cur", [("ForeignBallScrew", "iq_ref"), ("ForeignZStage", "iq_cmd")])
def test_same_seed_same_outputs(name, cur, plants):
    outs = ["iq_meas", "load_cell", "thrust_force"]

    def once(seed):
        p = plants(name, {"seed": seed, "surface_pos": 0.05})
        p.set(cur, 400.0)
        return p.run(800, 1e-4, outs)
    a, b, c = once(3), once(3), once(4)
    assert np.array_equal(a, b)
    assert not np.array_equal(a[:, 0], c[:, 0])
    assert np.max(a[:, 2]) > 1.0                          # it did cut


@pytest.mark.parametrize("name,params,words", [
    ("ForeignBallScrew", {"n_layers": 5}, "n_layers = 5"),
    ("ForeignBallScrew", {"n_layers": 2, "t2": 0.0}, "t2 = 0 mm"),
    ("ForeignBallScrew", {"T_stat": 0.01}, "T_stat = 0.01 N.m"),
    ("ForeignZStage", {"mass": -1.0}, "mass = -1 kg"),
    ("ForeignZStage", {"mat3": 7, "n_layers": 3, "t3": 1.0}, "mat3 = 7"),
])
def test_bad_parameter_refused(name, params, words):
    path = str(fmu_path(name))
    md = read_model_description(path)
    d = extract(path)
    msgs = []
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="bad")
    fmu.instantiate(logMessage=lambda env, st, cat, msg: msgs.append(msg.decode()))
    try:
        fmu.enterInitializationMode(startTime=0.0)
        vars_ = {v.name: v for v in md.modelVariables}
        for k, x in params.items():
            v = vars_[k]
            (fmu.setInt32 if v.type == "Int32" else fmu.setFloat64)([v.valueReference], [x])
        with pytest.raises(FMICallException):
            fmu.exitInitializationMode()
        assert any(words in m and "fmi3ExitInitializationMode" in m for m in msgs), msgs
    finally:
        fmu.freeInstance()
        shutil.rmtree(d, ignore_errors=True)


def test_tunable_refused_while_stepping(plants):
    p = plants("ForeignBallScrew")
    p.step(1e-4)
    with pytest.raises(FMICallException):
        p.set("Kt", -1.0)
    assert "Kt = -1 N.m/A is out of range" in p.messages[-1]
    assert p.get("thrust_force").size == 1
    with pytest.raises(FMICallException):
        p.set("lead", 5.0)                                 # fixed
    assert "lead is a fixed parameter" in p.messages[-1]


# ------------------------------------------------------------------ ForeignZStage

def test_zs_free_acceleration_with_gravity(plants):
    """i = 2 A in air: mean acceleration over 10-40 ms = (Kf i + m g - F_bal - F_coul
    - c mean(v) - mean cogging over the positions passed) / m (the Stribeck term is
    e^-(v/3 mm/s)^1.5 < 1e-4 after 10 ms). 1 %."""
    p = plants("ForeignZStage", AIR_ZS)
    i = 2.0
    p.set("iq_cmd", i * 1e3)
    dt = 1e-4
    o = p.run(400, dt, ["stage_vel", "tip_pos"])
    v, z = o[:, 0] * 1e-3, o[:, 1] * 1e-6
    a, b = 100, 399
    acc = (v[b] - v[a]) / ((b - a) * dt)
    k = 2 * np.pi / 12e-3
    cog = np.mean(1.2 * np.sin(k * z[a:b + 1]) + 0.5 * np.sin(2 * k * z[a:b + 1] + 0.7))
    F = (ZS["Kf"] * i + ZS["mass"] * ZS["g"] - ZS["F_bal"] - ZS["F_coul"] - ZS["c_visc"] * np.mean(v[a:b + 1])
         - cog)
    assert acc == pytest.approx(F / ZS["mass"], rel=0.01)


def test_zs_encoder_quantisation(plants):
    p = plants("ForeignZStage", AIR_ZS)
    p.set("iq_cmd", 500.0)
    o = p.run(300, 1e-4, ["z_meas", "tip_pos"])
    steps = o[:, 0] / 0.01                                 # 10 nm
    assert np.allclose(steps, np.round(steps), atol=1e-6)
    assert np.all((o[:, 1] - o[:, 0] >= -1e-9) & (o[:, 1] - o[:, 0] < 0.01 + 1e-9))


@pytest.mark.parametrize("v", [1e-3, 3e-3, 10e-3])
def test_zs_stribeck_curve(plants, v):
    """Air move at constant velocity (PI on true stage_vel, gravity fed forward, cogging off):
    mean Kf iq_meas + m g - F_bal = F_coul + (F_stat - F_coul) exp(-(v/v_strb)^1.5) + c v;
    2 % (25 mA noise over 0.4 s averages to 0.4 mA = 0.01 N)."""
    p = plants("ForeignZStage", {**AIR_ZS, "cog1": 0.0, "cog2": 0.0})
    m = ZS["mass"]
    wc = 2 * np.pi * 60          # gain wc m = 1600 N s/m beats the Stribeck slope (<= 700 N s/m)
    dt = 2e-4
    grav = m * ZS["g"] - ZS["F_bal"]
    st = {"i": 0.0}

    def control(pl):
        e = v - pl.get("stage_vel")[0] * 1e-3
        st["i"] += e * dt
        F = wc * m * e + wc * wc / 4 * m * st["i"] + ZS["F_coul"] - grav
        pl.set("iq_cmd", 1e3 * F / ZS["Kf"])
    o = p.run(6000, dt, ["iq_meas", "stage_vel"], control)
    tail = o[4000:]
    assert np.mean(tail[:, 1]) * 1e-3 == pytest.approx(v, rel=0.005)
    F_meas = ZS["Kf"] * np.mean(tail[:, 0]) * 1e-3 + grav
    expected = (ZS["F_coul"] + (ZS["F_stat"] - ZS["F_coul"]) * np.exp(-(v / ZS["v_strb"]) ** ZS["strb_exp"])
                + ZS["c_visc"] * v)
    assert F_meas == pytest.approx(expected, rel=0.02)


def test_zs_cogging_pitch(plants):
    """Constant velocity 20 mm/s over 3 pitches (36 mm): the motor force needed, resampled
    over position, has lines at 1/12 mm (1.2 N) and 2/12 mm (0.5 N), none at the project
    plant's 16 mm pitch. 10 % (current noise and loop residue)."""
    p = plants("ForeignZStage", AIR_ZS)
    m = ZS["mass"]
    v = 20e-3
    wc = 2 * np.pi * 60
    dt = 2e-4
    grav = m * ZS["g"] - ZS["F_bal"]
    st = {"i": 0.0}

    def control(pl):
        e = v - pl.get("stage_vel")[0] * 1e-3
        st["i"] += e * dt
        F = wc * m * e + wc * wc / 4 * m * st["i"] + ZS["F_coul"] + ZS["c_visc"] * v - grav
        pl.set("iq_cmd", 1e3 * F / ZS["Kf"])
    p.run(500, dt, ["stage_vel"], control)
    o = p.run(9000, dt, ["iq_meas", "tip_pos"], control)
    F = ZS["Kf"] * o[:, 0] * 1e-3
    z = o[:, 1] * 1e-3                                     # mm
    grid = z[0] + np.linspace(0, 36.0, 36 * 16, endpoint=False)
    spec = 2 * np.abs(np.fft.rfft(np.interp(grid, z, F))) / len(grid)
    assert spec[3] == pytest.approx(1.2, rel=0.10)        # 36 mm / 12 mm = 3 periods
    assert spec[6] == pytest.approx(0.5, rel=0.10)
    assert spec[int(round(36 / 16))] < 0.15                # no 16 mm line (bin 2 = 18 mm)


def test_zs_aluminium_thrust(plants):
    """Aluminium at 1 mm/s and 3000 rpm (0.02 mm/rev): K_al 0.02^0.8 = 50.3 N (Keio Fig. 3/7
    level). Relaxation x e / v = 2 ms; 1 %."""
    p = plants("ForeignZStage", {"n_layers": 1, "mat1": 3, "t1": 3.0, "surface_pos": 0.02})
    dt = 2e-4
    o = p.run(6000, dt, ["thrust_force", "material_id"], feed_loop_zs(1e-3, dt=dt))
    assert np.mean(o[-1500:, 0]) == pytest.approx(LAW["K_al"] * 0.02 ** LAW["x"], rel=0.01)
    assert 49.0 < np.mean(o[-1500:, 0]) < 52.0
    assert o[-1, 1] == 3


def test_zs_contact_lightly_damped(plants):
    """Spindle stopped, the tip at rest on a pre-drilled front, friction off: the stage on
    the contact spring rings at sqrt(k/m)/2pi = 345 Hz with zeta = (d_contact + c_visc) /
    (2 sqrt(k m)) = 0.019; 2 % and 15 %."""
    p = plants("ForeignZStage", {"surface_pos": -0.05, "F_coul": 0.0, "F_stat": 0.0, "cog1": 0.0,
                                 "cog2": 0.0})
    p.set("spindle_n", 0.0)
    p.set("iq_cmd", 2000.0)
    dt = 2e-5
    F = p.run(2500, dt, ["thrust_force"])[:, 0]
    t = dt * np.arange(1, 2501)
    f, zeta = damped_fit(t[100:], F[100:])
    k, m = ZS["k_contact"], ZS["mass"]
    assert f == pytest.approx(np.sqrt(k / m) / (2 * np.pi) * np.sqrt(1 - zeta ** 2), rel=0.02)
    assert zeta == pytest.approx((ZS["d_contact"] + ZS["c_visc"]) / (2 * np.sqrt(k * m)), rel=0.15)
    assert zeta < 0.1


# ------------------------------------------------------------------ plant binding files

@pytest.mark.parametrize("binding,name", [("foreign_ballscrew", "ForeignBallScrew"),
                                          ("foreign_zstage", "ForeignZStage")])
def test_binding_files_name_real_variables_in_convertible_units(binding, name):
    """scenarios/plants/<binding>.toml, through the master's binding loader, binds every role
    the FMU has to a variable that exists with a unit that converts to the contract's SI
    unit (or a stated scale); parameter roles name parameters. Spot checks of the factors."""
    from drillcosim.cosim.scenario.binding import load_binding
    from drillcosim.cosim.fmi.slave import load_model
    root = HERE.parent.parent
    b = load_binding(root / "scenarios" / "plants" / f"{binding}.toml")
    assert b.path == name
    b.bind(load_model(fmu_path(name)))
    expected = {"i_ref", "spindle_speed", "i_meas", "table_position", "thrust_dyn", "thrust_true",
                "tool_position_true", "velocity_true", "friction_true", "layer_index", "material_index"}
    if b.kind == "ball_screw":
        expected |= {"orbital_speed", "motor_angle", "ripple_true", "motor_speed_true"}
        assert b.bound["motor_angle"].scale == pytest.approx(np.pi / 180)        # deg -> rad
        assert b.bound["orbital_speed"].scale == pytest.approx(2 * np.pi)      # Hz -> rad/s, stated
        assert b.bound["table_position"].scale == pytest.approx(1e-3)          # mm -> m
    else:
        assert b.bound["table_position"].scale == pytest.approx(1e-6)          # um -> m
    assert set(b.bound) == expected
    assert b.bound["i_ref"].scale == pytest.approx(1e-3)                        # mA -> A
    assert b.bound_parameters and all(v.variable for v in b.bound_parameters.values())
