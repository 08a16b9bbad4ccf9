#!/usr/bin/env python3
"""Proving-ground recordings for `mrtwin diagnose`: an independent two-chamber MR damper
simulator with randomised geometry, fluid law, hidden effects, excitation and a rig-like
measurement chain. Deterministic per seed.

    python generate.py --seed 7 --out rec.csv --meta rec.json

`scenario(seed)` returns (meta, rec) with rec a dict of equal-length numpy arrays named
after the CSV columns. See README.md for what is drawn and how.
"""
import argparse
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pin_blas  # noqa: E402,F401  (before numpy: the same kernels on every machine)

import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

import physics  # noqa: E402
from physics import P  # noqa: E402

EFFECTS = ("fluid_compressibility", "gas_spring", "seal_friction", "thermal_softening",
           "field_lag", "fluid_inertia")
P_ATM = 101325.0

# Nominal geometries. F_nom: force at I_max and ~50 mm/s (yield dominated).
GEOMETRIES = {
    "seat_small": dict(Dp=36e-3, drod=10e-3, h=0.7e-3, L=12e-3, r=16e-3, F_nom=2.2e3,
                       note="LORD MRD-1003-5-like seat damper"),
    "mid_5kN": dict(Dp=50e-3, drod=16e-3, h=1.0e-3, L=25e-3, r=22e-3, F_nom=5e3,
                    note="mid-size vehicle damper"),
    "civil_20kN": dict(Dp=80e-3, drod=30e-3, h=1.5e-3, L=60e-3, r=36e-3, F_nom=20e3,
                       note="large civil-engineering damper"),
}


def _streams(seed):
    ss = np.random.SeedSequence(seed)
    names = ("plan", "geometry", "fluid", "excitation", "effects", "measurement")
    return {n: np.random.default_rng(s) for n, s in zip(names, ss.spawn(len(names)))}


def plan(seed):
    """Hidden-effect set of a seed (cheap: the first draws of its own stream)."""
    rng = _streams(seed)["plan"]
    n = int(rng.choice(4, p=[0.25, 0.35, 0.25, 0.15]))
    idx = sorted(rng.choice(len(EFFECTS), size=n, replace=False).tolist())
    return [EFFECTS[i] for i in idx]


# ---------------------------------------------------------------------------------------
# drawing the damper


def draw_geometry(rng):
    name = list(GEOMETRIES)[int(rng.integers(len(GEOMETRIES)))]
    g = GEOMETRIES[name]
    j = lambda: rng.uniform(0.87, 1.15)  # noqa: E731
    Dp, drod = g["Dp"] * j(), g["drod"] * j()
    h = g["h"] * rng.uniform(0.75, 1.35)
    L = g["L"] * j()
    r = min(g["r"] * j(), 0.5 * Dp - 2 * h)
    Ap = math.pi * Dp ** 2 / 4
    Ar = math.pi * drod ** 2 / 4
    A1 = Ap - Ar
    half_stroke = 0.02
    V10 = A1 * (half_stroke + rng.uniform(0.01, 0.03))
    V20 = Ap * (half_stroke + rng.uniform(0.01, 0.03))
    return dict(name=name, note=g["note"], Dp=Dp, d_rod=drod, h=h, L=L, r_mean=r,
                b=2 * math.pi * r, Ap=Ap, Ar=Ar, A1=A1, V10=V10, V20=V20,
                F_nom=g["F_nom"] * rng.uniform(0.8, 1.25))


def draw_fluid(rng, geo):
    law = int(rng.integers(4))
    I_max = float(rng.uniform(1.0, 2.0))
    shape = int(rng.integers(3))
    I_s = I_max * rng.uniform(0.3, 0.8)
    s = I_max / I_s
    f_max = [math.tanh(s), s * s / (1 + s * s), 1 - math.exp(-s ** 1.5)][shape]
    tau_at_max = 0.9 * geo["F_nom"] * geo["h"] / (2 * geo["L"] * geo["A1"])
    tau_sat = tau_at_max / f_max
    fl = dict(law=physics.FLUID_LAWS[law], law_code=law, I_max=I_max,
              yield_shape=["tanh", "quadratic_saturating", "stretched_exp"][shape],
              yield_shape_code=shape, I_s=I_s, tau_sat=tau_sat,
              tau_off=tau_sat * rng.uniform(0.0, 0.03),
              mu0=float(rng.uniform(0.06, 0.2)), mu_I=float(rng.uniform(0.0, 0.5)),
              rho=float(rng.uniform(2900, 3150)),
              n_hb=float(rng.uniform(0.7, 1.0)) if law == 1 else 1.0,
              visc_ratio=float(rng.uniform(50, 500)) if law == 2 else 1.0,
              m_pap=float(math.exp(rng.uniform(math.log(2e-3), math.log(5e-2)))) if law == 3 else 0.0)
    return fl


def base_params(geo, fl, rng):
    p = physics.empty_params()
    for k in ("A1", "Ap", "Ar", "b", "h", "L", "V10", "V20"):
        p[P[k]] = geo[k]
    p[P["tau_sat"]], p[P["tau_off"]], p[P["I_s"]] = fl["tau_sat"], fl["tau_off"], fl["I_s"]
    p[P["yield_shape"]] = fl["yield_shape_code"]
    p[P["mu0"]], p[P["mu_I"]], p[P["I_max"]] = fl["mu0"], fl["mu_I"], fl["I_max"]
    p[P["n_hb"]], p[P["visc_ratio"]], p[P["m_pap"]] = fl["n_hb"], fl["visc_ratio"], max(fl["m_pap"], 1e-6)
    p[P["rho"]] = fl["rho"]
    p[P["law"]] = fl["law_code"]
    # accumulator precharge (absolute): high enough that chamber 1 does not cavitate
    dp_max = 1.3 * geo["F_nom"] / geo["A1"]
    p[P["p0"]] = P_ATM + dp_max * rng.uniform(1.1, 1.5)
    p[P["p_atm"]] = P_ATM
    p[P["Vg0"]] = 1.0
    p[P["kappa"]] = 1.0
    p[P["K_liq"]], p[P["alpha_air"]], p[P["n_air"]] = 1.5e9, 0.0, 1.0
    p[P["p_vap"]] = 3e3
    p[P["nsub"]] = 2
    p[P["Fc"]] = p[P["Fs"]] = 1.0
    p[P["v_s"]], p[P["sigma0"]] = 1.0, 1.0
    p[P["tau_a"]] = p[P["tau_b"]] = 1e-3
    p[P["T_amb"]] = rng.uniform(18, 30)
    return p


# ---------------------------------------------------------------------------------------
# excitation


FINE_OVERSAMPLING = 16
FINE_GRID_HZ = 8000.0


def draw_excitation(rng, fl, forced_steps):
    fs = int(rng.choice([200, 500, 1000, 2000, 2500, 5000]))
    duration = float(min(20000 / fs, rng.uniform(8.0, 30.0)))
    n = int(round(duration * fs))
    # fine-grid oversampling: the recorded force converges in it (the reversal's step mean
    # in physics.simulate; check_generator.py measures it): <= 0.1 sigma_F from a 4x finer grid
    m = max(FINE_OVERSAMPLING, int(math.ceil(FINE_GRID_HZ / fs)))
    fsi = fs * m
    ni = n * m
    t = np.arange(ni) / fsi
    kind = str(rng.choice(["sines", "multisine", "random"]))
    vlim = 0.5
    segs = []
    if kind == "sines":
        nseg = int(rng.integers(3, 7))
        tseg = duration / nseg
        x = np.zeros(ni)
        for s in range(nseg):
            A = rng.uniform(3e-3, 15e-3)
            f = rng.uniform(0.5, 8.0)
            f = min(f, vlim / (2 * math.pi * A))
            cyc = max(1, int(round(f * tseg)))
            f = cyc / tseg
            sel = (t >= s * tseg) & (t < (s + 1) * tseg)
            # reversals fall between fine-grid samples (a sample at exactly v = 0 would
            # make the incompressible reference's force there arbitrary)
            x[sel] = A * np.sin(2 * math.pi * f * (t[sel] - s * tseg + 0.37 / fsi))
            segs.append(dict(t0=s * tseg, t1=(s + 1) * tseg, amplitude_m=A, freq_hz=f))
    elif kind == "multisine":
        nc = int(rng.integers(3, 7))
        freqs = np.sort(rng.uniform(0.5, 8.0, nc))
        ph = rng.uniform(0, 2 * math.pi, nc)
        amp = rng.uniform(0.3, 1.0, nc) / freqs ** rng.uniform(0.0, 1.0)
        x = sum(a_ * np.sin(2 * math.pi * f_ * t + p_) for a_, f_, p_ in zip(amp, freqs, ph))
        A = rng.uniform(3e-3, 15e-3)
        x *= A / np.max(np.abs(x))
        segs.append(dict(freqs_hz=freqs.tolist(), peak_m=A))
    else:
        f_hi = rng.uniform(2.0, 8.0)
        sos = signal.butter(4, [0.2, f_hi], btype="bandpass", fs=fsi, output="sos")
        x = signal.sosfiltfilt(sos, rng.standard_normal(ni))
        A = rng.uniform(3e-3, 15e-3)
        x *= A / np.max(np.abs(x))
        segs.append(dict(band_hz=[0.2, f_hi], peak_m=A))
    # actuator bandwidth (zero-phase, the rig's controller tracks the command) and a ramp-in
    sos = signal.butter(2, 30.0, fs=fsi, output="sos")
    x = signal.sosfiltfilt(sos, x)
    ramp = np.clip(t / 0.3, 0, 1)
    x *= 0.5 - 0.5 * np.cos(math.pi * ramp)
    v = np.gradient(x, 1 / fsi)
    vmax = np.max(np.abs(v))
    if vmax > vlim:
        x *= vlim / vmax
    v = np.gradient(x, 1 / fsi)
    a = np.gradient(v, 1 / fsi)

    # current command
    modes = ["held", "stepped", "random"]
    mode = str(rng.choice(modes[1:] if forced_steps else modes))
    I_max = fl["I_max"]
    icmd = np.zeros(ni)
    if mode == "held":
        if kind == "sines":
            edges = [(s_["t0"], s_["t1"]) for s_ in segs]
        else:
            k = int(rng.integers(3, 6))
            edges = [(i * duration / k, (i + 1) * duration / k) for i in range(k)]
        levels = rng.uniform(0, 1, len(edges)) * I_max
        levels[int(rng.integers(len(levels)))] = 0.0 if rng.random() < 0.5 else levels[0]
        for (t0, t1), lev in zip(edges, levels):
            icmd[(t >= t0) & (t < t1)] = lev
        cur = dict(mode=mode, levels_A=levels.tolist())
    elif mode == "stepped":
        nl = int(rng.integers(3, 5))
        levels = np.sort(rng.uniform(0, 1, nl)) * I_max
        levels[0] = 0.0 if rng.random() < 0.6 else levels[0]
        dwell = rng.uniform(0.3, 1.0)
        idx = (t // dwell).astype(int) % nl
        icmd = levels[idx]
        cur = dict(mode=mode, levels_A=levels.tolist(), dwell_s=dwell)
    else:
        tt = 0.0
        while tt < duration:
            d = rng.uniform(0.3, 1.0)
            icmd[(t >= tt) & (t < tt + d)] = rng.uniform(0, 1) * I_max
            tt += d
        cur = dict(mode=mode)
    exc = dict(kind=kind, duration_s=duration, fs_hz=fs, oversampling=m, segments=segs,
               current=cur, peak_velocity_m_s=float(np.max(np.abs(v))))
    return exc, t, x, v, a, icmd


# ---------------------------------------------------------------------------------------
# measurement chain


def draw_measurement(rng, fs):
    return dict(
        aa_cutoff_hz=fs * rng.uniform(0.2, 0.4),
        sigma_x_m=rng.uniform(1e-6, 5e-6),
        velocity=str(rng.choice(["central_difference", "savitzky_golay", "sensor"])),
        sigma_v_rel=rng.uniform(0.005, 0.02),
        force_noise_rel=rng.uniform(0.005, 0.02),
        force_noise_ar1=float(rng.uniform(0.3, 0.8)) if rng.random() < 0.5 else 0.0,
        force_offset_rel=float(rng.choice([-1, 1]) * rng.uniform(0.005, 0.03)) if rng.random() < 0.5 else 0.0,
        sigma_I_A=rng.uniform(0.002, 0.005),
        temperature_column=bool(rng.random() < 0.3),
        temperature_sensor_tau_s=rng.uniform(1.0, 4.0),
        noise_seed=int(rng.integers(2 ** 31)),
    )


def aa_filter(y, fsi, fc, m):
    """2nd-order Butterworth anti-alias filter (causal, as in the analog front end), then
    keep every m-th sample."""
    sos = signal.butter(2, fc, fs=fsi, output="sos")
    zi = signal.sosfilt_zi(sos) * y[0]
    return signal.sosfilt(sos, y, zi=zi)[0][::m]


class Rig:
    """Fine-grid excitation + measurement settings; runs the physics and the clean chain."""

    def __init__(self, exc, t, x, v, a, icmd, meas):
        self.exc, self.t, self.x, self.v, self.a, self.icmd, self.meas = exc, t, x, v, a, icmd, meas
        self.m = exc["oversampling"]
        self.fsi = exc["fs_hz"] * self.m
        self.dt = 1.0 / self.fsi

    def run(self, p):
        F, T, If, Q, Fh = physics.simulate(self.x, self.v, self.a, self.icmd, self.dt, p)
        return F, T

    def clean_force(self, p):
        F, _ = self.run(p)
        return aa_filter(F, self.fsi, self.meas["aa_cutoff_hz"], self.m)


# ---------------------------------------------------------------------------------------
# hidden effects: reference parameters and a scale s (effect parameter = s x reference)


def draw_effect_settings(rng, geo, fl, p, exc):
    xpk = max(abs(exc["peak_x"]), 1e-3)
    return {
        "fluid_compressibility": dict(K_liq_ref=1.0e9, alpha_air_ref=float(rng.uniform(0.002, 0.02)),
                                      n_air=float(rng.uniform(1.0, 1.4))),
        "gas_spring": dict(kappa=float(rng.uniform(1.0, 1.4)),
                           Vg0_ref=geo["Ar"] * xpk / rng.uniform(0.1, 0.3)),
        "seal_friction": dict(kind=str(rng.choice(["stribeck", "dahl", "lugre"])),
                              Fc_ref=0.02 * geo["F_nom"], Fs_over_Fc=float(rng.uniform(1.2, 1.8)),
                              v_s=float(rng.uniform(2e-3, 1e-2)),
                              x_presliding=float(rng.uniform(2e-5, 1e-4)),
                              sigma1_per_Fc=float(rng.uniform(0.5, 3.0)),
                              sigma2_per_Fc=float(rng.uniform(0.0, 0.3))),
        "thermal_softening": dict(law=str(rng.choice(["exponential", "linear"])),
                                  beta_tau_ref=float(rng.uniform(0.002, 0.006)),
                                  beta_mu_ref=float(rng.uniform(0.01, 0.03))),
        "field_lag": dict(kind=str(rng.choice(["first_order", "second_order", "coil_driver"])),
                          tau_ref=0.010, split=float(rng.uniform(0.3, 0.7)),
                          driver_gain=float(rng.uniform(2.0, 8.0)),
                          rail_ratio=float(rng.uniform(1.5, 4.0))),
        "fluid_inertia": dict(kind=str(rng.choice(["gap_fluid", "moving_mass", "both"])),
                              m_rod_ref=geo["F_nom"] / 2e3 * 0.5),
    }


def apply_effect(p, eff, st, s):
    """Switch effect `eff` on in params p with scale s; returns the physical parameters."""
    if eff == "fluid_compressibility":
        p[P["comp_on"]] = 1
        p[P["K_liq"]] = st["K_liq_ref"] / s
        p[P["alpha_air"]] = min(0.3, st["alpha_air_ref"] * s)
        p[P["n_air"]] = st["n_air"]
        return dict(K_liq_Pa=p[P["K_liq"]], air_fraction_at_p0=p[P["alpha_air"]], n_air=st["n_air"],
                    effective_K_at_p0_Pa=1.0 / ((1 - p[P["alpha_air"]]) / p[P["K_liq"]]
                                               + p[P["alpha_air"]] / (st["n_air"] * p[P["p0"]])))
    if eff == "gas_spring":
        p[P["gas_on"]] = 1
        p[P["Vg0"]] = st["Vg0_ref"] / s
        p[P["kappa"]] = st["kappa"]
        # p_g = p0 (Vg0 / (Vg0 + Ar x))^kappa: extension (x > 0) draws the rod out and
        # lets the gas expand, so the gas force -(p_g - p_atm) Ar is a positive spring
        return dict(p0_abs_Pa=p[P["p0"]], Vg0_m3=p[P["Vg0"]], kappa=st["kappa"],
                    offset_N=-(p[P["p0"]] - P_ATM) * p[P["Ar"]],
                    stiffness_at_0_N_m=st["kappa"] * p[P["p0"]] * p[P["Ar"]] ** 2 / p[P["Vg0"]])
    if eff == "seal_friction":
        Fc = st["Fc_ref"] * s
        p[P["fric_on"]] = 1
        p[P["fric_type"]] = ["stribeck", "dahl", "lugre"].index(st["kind"])
        p[P["Fc"]], p[P["Fs"]], p[P["v_s"]] = Fc, Fc * st["Fs_over_Fc"], st["v_s"]
        p[P["sigma0"]] = Fc / st["x_presliding"]
        p[P["sigma1"]] = Fc * st["sigma1_per_Fc"] if st["kind"] == "lugre" else 0.0
        p[P["sigma2"]] = Fc * st["sigma2_per_Fc"]
        return dict(kind=st["kind"], Fc_N=Fc, Fs_N=p[P["Fs"]], v_s=st["v_s"],
                    sigma0_N_m=p[P["sigma0"]], sigma1_Ns_m=p[P["sigma1"]], sigma2_Ns_m=p[P["sigma2"]])
    if eff == "thermal_softening":
        p[P["therm_on"]] = 1
        p[P["therm_law"]] = 0 if st["law"] == "exponential" else 1
        p[P["beta_tau"]], p[P["beta_mu"]] = st["beta_tau_ref"] * s, st["beta_mu_ref"] * s
        return dict(law=st["law"], beta_tau_per_K=p[P["beta_tau"]], beta_mu_per_K=p[P["beta_mu"]])
    if eff == "field_lag":
        tau = st["tau_ref"] * s
        p[P["lag_on"]] = 1
        kind = st["kind"]
        p[P["lag_type"]] = ["first_order", "second_order", "coil_driver"].index(kind)
        if kind == "first_order":
            p[P["tau_a"]], p[P["tau_b"]] = tau, tau
        elif kind == "second_order":
            p[P["tau_a"]], p[P["tau_b"]] = tau * st["split"], tau * (1 - st["split"])
        else:
            # closed current loop ~ L/R / (1 + gain), plus the eddy-current lag
            p[P["tau_a"]] = tau * st["split"] * (1 + st["driver_gain"])
            p[P["tau_b"]] = tau * (1 - st["split"])
            p[P["drv_gain"]], p[P["V_max_ratio"]] = st["driver_gain"], st["rail_ratio"]
        return dict(kind=kind, effective_tau_s=tau, tau_a_s=p[P["tau_a"]], tau_b_s=p[P["tau_b"]],
                    driver_gain=st["driver_gain"] if kind == "coil_driver" else None,
                    rail_ratio=st["rail_ratio"] if kind == "coil_driver" else None)
    if eff == "fluid_inertia":
        kind = st["kind"]
        # reference: the physical gap-fluid mass rho L A1^2/(b h) (scale 1) and a rod mass
        p[P["m_gap_scale"]] = s if kind in ("gap_fluid", "both") else 0.0
        p[P["m_rod"]] = st["m_rod_ref"] * s if kind in ("moving_mass", "both") else 0.0
        mg = p[P["rho"]] * p[P["L"]] * p[P["A1"]] ** 2 / (p[P["b"]] * p[P["h"]])
        return dict(kind=kind, gap_fluid_mass_kg=mg * p[P["m_gap_scale"]],
                    gap_length_factor=p[P["m_gap_scale"]], moving_mass_kg=p[P["m_rod"]])
    raise ValueError(eff)


# Scale bounds of the sizing. Compressibility: K_liq between 5e7 and 2e10 Pa (air fraction
# between 5 % and 20x its drawn reference, at most 30 %). Stiffer than 2e10 Pa (ten times
# mineral oil) the "effect" the sizing finds is no longer compliance: with the fluid all
# but rigid, the pressure a yield-stress plug locks in at standstill is set by the
# integrator's last steps (kN either way on seed 7 at K_eff 1.5e17 Pa), so a record
# labelled compressible would carry a numerical artefact. Where the target size cannot
# be reached inside the bounds, the effect is larger than the target (meta: u_achieved).
LIMITS = {"field_lag": (0.1, 6.0),               # effective lag 1-60 ms (nominal 3-30 ms)
          "fluid_compressibility": (0.05, 20.0)}


def absorbable_basis(rig):
    """Columns the null model can move along without any hidden effect: per current level
    (hat functions over the held levels, or 6 knots when the current is random) a Coulomb
    step sign(v) and a viscous term v, both through the measurement chain, plus a constant
    offset. The part of an effect in their span is a different yield stress, viscosity or
    sensor offset, not missing physics (a Coulomb seal friction is exactly a field-off
    yield); what is left is what any method could detect."""
    fc, m, I, v = rig.meas["aa_cutoff_hz"], rig.m, rig.icmd, rig.v
    lev = np.unique(np.round(I, 6))
    knots = lev if len(lev) <= 8 else np.linspace(I.min(), I.max(), 6)
    cols = []
    for k in range(len(knots)):
        h = np.ones_like(I) if len(knots) == 1 else np.interp(I, knots, (np.arange(len(knots)) == k) * 1.0)
        cols.append(aa_filter(h * np.sign(v), rig.fsi, fc, m))
        cols.append(aa_filter(h * v, rig.fsi, fc, m))
    cols.append(np.ones(len(cols[0])))
    return np.column_stack(cols)


def unabsorbed_rms(B, d):
    """RMS of d after its least-squares projection onto the absorbable columns B."""
    c, *_ = np.linalg.lstsq(B, d, rcond=None)
    return float(np.sqrt(np.mean((d - B @ c) ** 2)))


def size_effect(rig, p_base, F_base, eff, st, target, tol=0.05, max_runs=9):
    """Scale s of `eff` so that RMS(F_with - F_without) = target (noise-free, measured
    force; mean removed for the gas spring). Linear scaling from a reference run (s = 1),
    then corrections: log-log secant, kept inside the bracket found so far (bisection in
    log s otherwise), until within `tol`. Compressibility needs the bracket: near a
    velocity reversal the blocked flow meets the Bingham jump, and the effect grows
    steeply with compliance."""
    def rms_for(s):
        p = p_base.copy()
        apply_effect(p, eff, st, s)
        d = rig.clean_force(p) - F_base
        if eff == "gas_spring":
            d = d - d.mean()
        return float(np.sqrt(np.mean(d * d)))

    lo_lim, hi_lim = LIMITS.get(eff, (1e-9, 1e9))
    hist = [(1.0, rms_for(1.0))]
    s = float(np.clip(target / max(hist[0][1], 1e-12), lo_lim, hi_lim))
    hist.append((s, rms_for(s)))
    while len(hist) < max_runs:
        s1, r1 = hist[-1]
        if abs(r1 / target - 1) <= tol:
            break
        if (s1 == hi_lim and r1 < target) or (s1 == lo_lim and r1 > target):
            break
        below = [h for h in hist if h[1] < target]
        above = [h for h in hist if h[1] >= target]
        blo = max(below)[0] if below else lo_lim
        bhi = min(above)[0] if above else hi_lim
        s0, r0 = hist[-2]
        k = math.log(max(r1, 1e-12) / max(r0, 1e-12)) / math.log(s1 / s0) if s1 != s0 else 1.0
        k = float(np.clip(k if np.isfinite(k) else 1.0, 0.2, 5.0))
        s2 = s1 * (target / max(r1, 1e-12)) ** (1 / k)
        if below and above and not (blo < s2 < bhi):
            s2 = math.sqrt(blo * bhi)
        s2 = float(np.clip(s2, lo_lim, hi_lim))
        hist.append((s2, rms_for(s2)))
    best = min(hist[1:], key=lambda h: abs(math.log(max(h[1], 1e-12) / target)))
    return best[0], best[1], hist


# ---------------------------------------------------------------------------------------


def scenario(seed, truth=None, null_twin=False):
    """Draw and simulate one scenario. Returns (meta dict, recording dict of arrays).

    `truth`: an optional dict, filled with what the fluid really had at each recorded
    sample (`yield_truth`); the recording and the meta do not depend on it.
    `null_twin`: the same scenario with nothing hidden (damper, fluid, excitation, heat and
    measurement drawn as for `seed`, each from its own stream): how far the base law alone
    sits from a model, without the hidden effects."""
    rs = _streams(seed)
    planned = plan(seed)
    hidden = [] if null_twin else planned
    geo = draw_geometry(rs["geometry"])
    fl = draw_fluid(rs["fluid"], geo)
    p_base = base_params(geo, fl, rs["fluid"])
    # A planned field lag forces current steps; the null twin keeps its seed's excitation.
    exc, t, x, v, a, icmd = draw_excitation(rs["excitation"], fl, "field_lag" in planned)
    exc["peak_x"] = float(np.max(np.abs(x)))
    meas = draw_measurement(rs["measurement"], exc["fs_hz"])
    rig = Rig(exc, t, x, v, a, icmd, meas)

    # heat balance (always physical; the effect is the coupling to yield/viscosity):
    # time constant C/G of 1-4 record lengths, C such that the drift is 5-20 K
    erng = rs["effects"]
    drift = float(erng.uniform(5.0, 20.0))
    tau_th = exc["duration_s"] * float(erng.uniform(1.0, 4.0))
    p_base[P["C_th"]], p_base[P["G_th"]] = 1.0, 1.0 / tau_th
    F0, T0 = rig.run(p_base)
    C = max(float(T0.max() - p_base[P["T_amb"]]) / drift, 1e-9)
    p_base[P["C_th"]], p_base[P["G_th"]] = C, C / tau_th

    F_base = rig.clean_force(p_base)
    F_rms = float(np.sqrt(np.mean(F_base ** 2)))
    sigma_F = meas["force_noise_rel"] * F_rms

    settings = draw_effect_settings(erng, geo, fl, p_base, exc)
    B_abs = absorbable_basis(rig)
    p = p_base.copy()
    effects_meta = []
    for eff in hidden:
        u_target = float(erng.uniform(1.0, 3.0))
        s, r, hist = size_effect(rig, p_base, F_base, eff, settings[eff], u_target * sigma_F)
        phys = apply_effect(p, eff, settings[eff], s)
        p_one = p_base.copy()
        apply_effect(p_one, eff, settings[eff], s)
        u_seen = unabsorbed_rms(B_abs, rig.clean_force(p_one) - F_base) / sigma_F
        effects_meta.append(dict(effect=eff, u_target=u_target, u_achieved=r / sigma_F,
                                 u_unabsorbed=u_seen,
                                 rms_effect_N=r, scale=s, parameters=phys,
                                 sizing_runs=[[float(a_), float(b_)] for a_, b_ in hist]))

    F, T, If, _Q, _Fh = physics.simulate(rig.x, rig.v, rig.a, rig.icmd, rig.dt, p)
    m = rig.m
    if truth is not None:
        truth.update(yield_truth(p, If, T, icmd, m))
    fc = meas["aa_cutoff_hz"]
    Fm = aa_filter(F, rig.fsi, fc, m)
    xm = aa_filter(x, rig.fsi, fc, m)
    vm = aa_filter(v, rig.fsi, fc, m)
    Im = aa_filter(icmd, rig.fsi, fc, m)
    Tm = T[::m]
    d_all = Fm - F_base
    if "gas_spring" in hidden:
        d_all = d_all - d_all.mean()
    u_combined = float(np.sqrt(np.mean(d_all ** 2)) / sigma_F)

    # noise
    nrng = np.random.default_rng(meas["noise_seed"])
    n = len(Fm)
    fs = exc["fs_hz"]
    time = np.arange(n) / fs
    x_rec = xm + meas["sigma_x_m"] * nrng.standard_normal(n)
    if meas["velocity"] == "central_difference":
        v_rec = np.gradient(x_rec, 1 / fs)
    elif meas["velocity"] == "savitzky_golay":
        w = max(5, int(round(0.004 * fs)) | 1)
        meas["savgol_window"] = w
        v_rec = signal.savgol_filter(x_rec, w, 2, deriv=1, delta=1 / fs)
    else:
        v_rec = vm + meas["sigma_v_rel"] * np.sqrt(np.mean(vm ** 2)) * nrng.standard_normal(n)
    rho_ar = meas["force_noise_ar1"]
    w_ = nrng.standard_normal(n) * math.sqrt(1 - rho_ar ** 2)
    e = signal.lfilter([1.0], [1.0, -rho_ar], w_) if rho_ar > 0 else w_
    e = e / max(np.std(e), 1e-12) * sigma_F if rho_ar > 0 else e * sigma_F
    offset = meas["force_offset_rel"] * F_rms
    F_rec = Fm + e + offset
    I_rec = Im + meas["sigma_I_A"] * nrng.standard_normal(n)
    rec = dict(time_s=time, displacement_m=x_rec, velocity_m_s=v_rec, force_N=F_rec,
               current_A=I_rec)
    if meas["temperature_column"]:
        a_t = math.exp(-1 / (fs * meas["temperature_sensor_tau_s"]))
        Ts = signal.lfilter([1 - a_t], [1, -a_t], Tm - Tm[0]) + Tm[0]
        rec["temperature_C"] = Ts + 0.05 * nrng.standard_normal(n)

    meta = dict(
        seed=seed, hidden=hidden, geometry=geo, fluid=fl,
        accumulator=dict(p0_abs_Pa=float(p_base[P["p0"]]),
                         note="gas force counted only when gas_spring is hidden"),
        thermal=dict(drift_K_target=drift, tau_thermal_s=tau_th, C_J_K=C,
                     drift_K=float(T.max() - T[0]), T_amb_C=float(p_base[P["T_amb"]])),
        effects=effects_meta, u_combined=u_combined, excitation=exc, measurement=meas,
        sigma_F_N=sigma_F, force_rms_N=F_rms, force_offset_N=offset, samples=n,
    )
    return meta, rec


def yield_truth(p, If, T, icmd, m):
    """The yield stress acting in the fluid at each recorded sample (every m-th fine
    sample, the instants of the recorded time column), by the simulation's own code path
    (physics.simulate): tau_y = yield_of_current(I_field) times the thermal factor of the
    temperature at that step when thermal_softening is on. I_field is the current the
    fluid sees (after the field lag / coil driver when field_lag is on, else the command).
    For every fluid law this is the law's yield-stress parameter tau0 (bi-viscous: the
    stress where the post-yield branch starts; Papanastasiou: the asymptotic yield
    stress). Instantaneous: the recorded channels' anti-alias filter delay (~1/(2 pi fc),
    a few ms) is not applied. Returns numpy arrays tau_y_Pa, current_field_A,
    current_command_A, temperature_C."""
    idx = np.arange(0, len(If), m)
    therm_on = p[P["therm_on"]] > 0.5
    t_amb, beta, law = p[P["T_amb"]], p[P["beta_tau"]], int(p[P["therm_law"]])
    tau = np.empty(len(idx))
    for j, k in enumerate(idx):
        tau0 = physics.yield_of_current(If[k], p)
        if therm_on:
            tau0 *= physics.thermal_factor(T[k] - t_amb, beta, law)
        tau[j] = tau0
    return dict(tau_y_Pa=tau, current_field_A=np.asarray(If[idx], dtype=float),
                current_command_A=np.asarray(icmd[idx], dtype=float),
                temperature_C=np.asarray(T[idx], dtype=float))


def truth(seed):
    """(meta, rec, truth) of `seed`: the scenario and its per-sample truth
    (`yield_truth`), from one simulation."""
    tr = {}
    meta, rec = scenario(seed, truth=tr)
    return meta, rec, tr


def base_law_rig(seed):
    """The scenario of `seed` and its base law alone on its fine-grid excitation: no hidden
    effect and no heating (for the floor and convergence checks). Returns
    (meta, rec, fl, p, exc, t, x, v, a, icmd)."""
    meta, rec = scenario(seed)
    rs = _streams(seed)
    geo = draw_geometry(rs["geometry"])
    fl = draw_fluid(rs["fluid"], geo)
    p = base_params(geo, fl, rs["fluid"])
    exc, t, x, v, a, icmd = draw_excitation(rs["excitation"], fl, "field_lag" in meta["hidden"])
    p[P["C_th"]], p[P["G_th"]] = 1e30, 1.0
    return meta, rec, fl, p, exc, t, x, v, a, icmd


def write_csv(path, rec):
    cols = list(rec)
    arr = np.column_stack([rec[c] for c in cols])
    np.savetxt(path, arr, delimiter=",", header=",".join(cols), comments="", fmt="%.9g")


def library_versions():
    """The numerics the scenarios are computed with: a seed's file is reproducible bit for
    bit only with the same versions (pinned in scripts/setup-venv.sh)."""
    import numba
    import scipy
    return {"numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__}


def _jsonable(o):
    if isinstance(o, dict):
        return {k: _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True, help="CSV recording to write")
    ap.add_argument("--meta", help="JSON with the hidden truth and all drawn settings")
    ap.add_argument("--null-twin", action="store_true",
                    help="the same scenario with nothing hidden (its null twin)")
    args = ap.parse_args(argv)
    meta, rec = scenario(args.seed, null_twin=args.null_twin)
    write_csv(args.out, rec)
    if args.meta:
        with open(args.meta, "w") as f:
            json.dump(_jsonable(meta), f, indent=1)
    print(f"seed {args.seed}: hidden {meta['hidden'] or 'none'}, {meta['samples']} samples "
          f"at {meta['excitation']['fs_hz']} Hz -> {args.out}")


if __name__ == "__main__":
    main()
