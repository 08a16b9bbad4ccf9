"""Numerical core of the proving-ground MR damper simulator (numba).

Independent of the project's Rust code: written from PHYSICS.md's conventions, the two
papers and textbook slit-flow / hydraulics. Everything here is in SI units with absolute
pressures. Conventions: x > 0 in extension, v = dx/dt, F > 0 when the damper resists
extension (a dashpot reads F = c v).

Layout of the single-rod damper (floating-piston accumulator on the far side):

    rod side (chamber 1, annulus A1 = Ap - Ar) | piston, gap h x L x b | chamber 2 (Ap) | gas

Extension (v > 0) squeezes chamber 1, fluid flows 1 -> 2 through the gap at rate Q.

Fluid laws (slit between plates of width b, height h, length L), written through the wall
stress tau_w = h |dp| / (2 L) and the "flow integral" Phi(tau_w) = int_0^tau_w tau*gdot(tau) dtau,
so that Q = 2 b L^2 Phi(tau_w) / dp^2 (exact for any generalised-Newtonian law):
    0 Bingham            tau = tau0 + mu gdot                 (Buckingham)
    1 Herschel-Bulkley   tau = tau0 + k gdot^n
    2 bi-viscous         tau = mu_pre gdot below tau_y, then tau_y + mu (gdot - tau_y/mu_pre)
    3 Papanastasiou      tau = mu gdot + tau0 (1 - exp(-m gdot))
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pin_blas  # noqa: E402,F401  (before numpy: the same kernels on every machine)

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

BINGHAM, HERSCHEL_BULKLEY, BIVISCOUS, PAPANASTASIOU = 0, 1, 2, 3
FLUID_LAWS = ("bingham", "herschel_bulkley", "biviscous", "papanastasiou")

# ---------------------------------------------------------------------------------------
# Parameter vector layout (float64). Names are kept in one place so generate.py and the
# checks fill the same slots.
P_NAMES = [
    # geometry
    "A1", "Ap", "Ar", "b", "h", "L", "V10", "V20",
    # fluid (values at the reference temperature; yield/visc as functions of current)
    "tau_sat", "tau_off", "I_s", "yield_shape", "mu0", "mu_I", "I_max", "n_hb", "visc_ratio",
    "m_pap", "rho",
    # accumulator / gas
    "p0", "p_atm", "Vg0", "kappa", "gas_on",
    # compressibility (entrained air mixture), scaled by comp_scale
    "comp_on", "K_liq", "alpha_air", "n_air", "p_vap", "nsub",
    # seal friction
    "fric_on", "fric_type", "Fc", "Fs", "v_s", "sigma0", "sigma1", "sigma2",
    # field lag
    "lag_on", "lag_type", "tau_a", "tau_b", "V_max_ratio", "drv_gain",
    # thermal
    "T_amb", "C_th", "G_th", "therm_on", "therm_law", "beta_tau", "beta_mu",
    # inertia
    "m_gap_scale", "m_rod",
    # fluid law code
    "law",
]
P = {name: i for i, name in enumerate(P_NAMES)}


def empty_params():
    return np.zeros(len(P_NAMES))


# ---------------------------------------------------------------------------------------
# Slit flow


@njit(cache=True)
def _s2(x):
    """1 - exp(-x)(1 + x), accurate for small x."""
    if x < 1e-3:
        return x * x * (0.5 - x / 3.0 + x * x / 8.0)
    return 1.0 - math.exp(-x) * (1.0 + x)


@njit(cache=True)
def _s3(x):
    """2 - exp(-x)(2 + 2x + x^2), accurate for small x."""
    if x < 1e-3:
        return x * x * x * (1.0 / 3.0 - x / 4.0 + x * x / 10.0)
    return 2.0 - math.exp(-x) * (2.0 + 2.0 * x + x * x)


@njit(cache=True)
def wall_rate_and_phi(law, tw, tau0, mu, n, ratio, m):
    """Wall shear rate gdot(tau_w) and Phi(tau_w) = int_0^tau_w tau gdot dtau."""
    if tw <= 0.0:
        return 0.0, 0.0
    if law == BINGHAM:
        if tw <= tau0:
            return 0.0, 0.0
        g = (tw - tau0) / mu
        phi = ((tw ** 3 - tau0 ** 3) / 3.0 - tau0 * (tw * tw - tau0 * tau0) / 2.0) / mu
        return g, phi
    if law == HERSCHEL_BULKLEY:
        if tw <= tau0:
            return 0.0, 0.0
        s = tw - tau0
        r = 1.0 / n
        kk = mu ** (-r)  # mu plays the consistency k here
        g = kk * s ** r
        phi = kk * (s ** (2.0 + r) / (2.0 + r) + tau0 * s ** (1.0 + r) / (1.0 + r))
        return g, phi
    if law == BIVISCOUS:
        mup = ratio * mu
        if tw <= tau0:
            return tw / mup, tw ** 3 / (3.0 * mup)
        g = tau0 / mup + (tw - tau0) / mu
        phi = (tau0 ** 3 / (3.0 * mup) + tau0 / mup * (tw * tw - tau0 * tau0) / 2.0
               + ((tw ** 3 - tau0 ** 3) / 3.0 - tau0 * (tw * tw - tau0 * tau0) / 2.0) / mu)
        return g, phi
    # Papanastasiou: invert tau(g) = mu g + tau0 (1 - exp(-m g)) (concave, Newton from 0
    # converges monotonically), then integrate tau g tau'(g) dg in closed form.
    g = 0.0
    for _ in range(60):
        e = math.exp(-m * g)
        f = mu * g + tau0 * (1.0 - e) - tw
        d = mu + tau0 * m * e
        dg = -f / d
        g += dg
        if abs(dg) <= 1e-13 * (g + 1e-300):
            break
    G = g
    x1 = m * G
    x2 = 2.0 * m * G
    phi = (mu * mu * G ** 3 / 3.0 + mu * tau0 * G * G / 2.0
           + (-mu * tau0 + tau0 * tau0 * m) * _s2(x1) / (m * m)
           + mu * tau0 * m * _s3(x1) / (m ** 3)
           - tau0 * tau0 * m * _s2(x2) / (4.0 * m * m))
    return G, phi


@njit(cache=True)
def slit_q(dp, law, b, h, L, tau0, mu, n, ratio, m):
    """Flow Q (m^3/s, sign of dp) through the slit and dQ/d(dp)."""
    a = abs(dp)
    if a <= 0.0:
        if law == BIVISCOUS:
            return 0.0, b * h ** 3 / (12.0 * ratio * mu * L)
        if law == PAPANASTASIOU:
            return 0.0, b * h ** 3 / (12.0 * (mu + tau0 * m) * L)
        return 0.0, 0.0
    tw = h * a / (2.0 * L)
    g, phi = wall_rate_and_phi(law, tw, tau0, mu, n, ratio, m)
    q = 2.0 * b * L * L * phi / (a * a)
    dq = 2.0 * b * L * L * (tw * g * h / (2.0 * L) / (a * a) - 2.0 * phi / (a ** 3))
    if dq < 0.0:
        dq = 0.0
    if dp < 0.0:
        return -q, dq
    return q, dq


@njit(cache=True)
def slit_dp(q, law, b, h, L, tau0, mu, n, ratio, m, guess):
    """Pressure drop that drives flow q (inverse of slit_q): bracketed Newton.

    For Bingham this is the positive root above dp_y of Buckingham's cubic
    dp^3 - (3/2 dp_y + q 12 mu L/(b h^3)) dp^2 + dp_y^3/2 = 0.
    """
    a = abs(q)
    if a == 0.0:
        return 0.0
    if law == BINGHAM or law == HERSCHEL_BULKLEY:
        lo = 2.0 * tau0 * L / h
    else:
        lo = 0.0
    hi = max(abs(guess), lo * 1.05 + 1.0)
    for _ in range(200):
        qh, _d = slit_q(hi, law, b, h, L, tau0, mu, n, ratio, m)
        if qh >= a:
            break
        lo = hi
        hi *= 2.0
    x = abs(guess)
    if not (lo < x < hi):
        x = 0.5 * (lo + hi)
    for _ in range(100):
        f, d = slit_q(x, law, b, h, L, tau0, mu, n, ratio, m)
        f -= a
        if f > 0.0:
            hi = x
        else:
            lo = x
        if abs(f) <= 1e-12 * a or hi - lo <= 1e-12 * hi:
            break
        xn = x - f / d if d > 0.0 else -1.0
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        x = xn
    return x if q > 0.0 else -x


# ---------------------------------------------------------------------------------------
# Fluid properties as functions of field current and temperature


@njit(cache=True)
def yield_of_current(I, p):
    I = abs(I)
    shape = int(p[11])
    s = I / p[10]
    if shape == 0:
        f = math.tanh(s)
    elif shape == 1:
        f = s * s / (1.0 + s * s)  # quadratic at low current, then saturating
    else:
        f = 1.0 - math.exp(-(s ** 1.5))
    return p[8] * f + p[9]


@njit(cache=True)
def visc_of_current(I, p):
    return p[12] * (1.0 + p[13] * min(abs(I), p[14]) / p[14])


@njit(cache=True)
def thermal_factor(dT, beta, law):
    if law == 0:
        return math.exp(-beta * dT)
    return max(0.2, 1.0 - beta * dT)


# ---------------------------------------------------------------------------------------
# Compressible chambers: entrained-air mixture, specific volume per unit reference volume
#   nu(p) = (1 - alpha) exp(-(p - p0)/K_liq) + alpha (p0/p)^(1/n_air)
# Fluid inventories (reference volumes) W are the states; pressure follows from V/W = nu(p).


@njit(cache=True)
def nu_of_p(pp, p0, K, alpha, nair):
    e = math.exp(-(pp - p0) / K)
    air = alpha * (p0 / pp) ** (1.0 / nair)
    return (1.0 - alpha) * e + air, -(1.0 - alpha) * e / K - air / (nair * pp)


@njit(cache=True)
def gas_volume(p2, p0, Vg0, kappa):
    v = Vg0 * (p0 / p2) ** (1.0 / kappa)
    return v, -v / (kappa * p2)


@njit(cache=True)
def chamber2_pressure(Wrest, x, p, K, alpha, guess):
    """Chamber 2 pressure such that its fluid inventory equals Wrest (gas behind a
    floating piston): (V20 + Vg0 + Ap x - Vg(p2)) / nu(p2) = Wrest."""
    Ap, V20, Vg0, kappa, p0, nair = p[1], p[7], p[21], p[22], p[19], p[27]
    Vt = V20 + Vg0 + Ap * x
    lo, hi = 1e3, 1e10
    y = guess
    for _ in range(80):
        nu, dnu = nu_of_p(y, p0, K, alpha, nair)
        vg, dvg = gas_volume(y, p0, Vg0, kappa)
        r = (Vt - vg) / nu - Wrest
        dr = -dvg / nu - (Vt - vg) * dnu / (nu * nu)
        if r > 0.0:
            hi = y
        else:
            lo = y
        if abs(r) <= 1e-14 * Wrest:
            break
        yn = y - r / dr
        if not (lo < yn < hi):
            yn = math.sqrt(lo * hi)
        y = yn
    return y


# ---------------------------------------------------------------------------------------
# Seal friction (state z: bristle deflection for LuGre, friction force for Dahl)


@njit(cache=True)
def reversal_split(v, a, dt):
    """Where the velocity (linear over the step, v at its centre, slope a) changes sign
    inside the step [-dt/2, dt/2]: (fraction before the reversal, mean velocity before,
    mean velocity after). (0, 0, 0) when it does not reverse."""
    va = v - 0.5 * dt * a
    vb = v + 0.5 * dt * a
    if va * vb >= 0.0:
        return 0.0, 0.0, 0.0
    th = 0.5 - v / (a * dt)
    return th, 0.5 * va, 0.5 * vb


@njit(cache=True)
def stribeck_level(v, p):
    """Sliding friction level g(v) = Fc + (Fs - Fc) exp(-(v/v_s)^2) (Stribeck and LuGre)."""
    Fc, Fs, vs = p[32], p[33], p[34]
    return Fc + (Fs - Fc) * math.exp(-(v / vs) ** 2)


@njit(cache=True)
def stribeck(v, p):
    """Stribeck static map: g(v) times a smoothed sign, plus viscous friction."""
    return stribeck_level(v, p) * math.tanh(v / (0.02 * p[34])) + p[37] * v


@njit(cache=True)
def friction_step(ftype, z, v, a, dt, p):
    Fc, s0, s1, s2 = p[32], p[35], p[36], p[37]
    if ftype == 0:  # Stribeck, static map (smoothed sign); mean over a reversing step
        th, va, vb = reversal_split(v, a, dt)
        if th > 0.0:
            return z, th * stribeck(va, p) + (1.0 - th) * stribeck(vb, p)
        return z, stribeck(v, p)
    dx = abs(v) * dt
    sg = 1.0 if v >= 0.0 else -1.0
    if ftype == 1:  # Dahl (exponent 1), exact for constant v over dt
        zs = sg * Fc
        zn = zs + (z - zs) * math.exp(-s0 * dx / Fc)
        return zn, zn + s2 * v
    # LuGre, exact for constant v over dt
    g = stribeck_level(v, p)
    zs = sg * g / s0
    zn = zs + (z - zs) * math.exp(-s0 * dx / g)
    dz = (zn - z) / dt
    return zn, s0 * zn + s1 * dz + s2 * v


# ---------------------------------------------------------------------------------------
# Main integrator


@njit(cache=True)
def simulate(x, v, a, icmd, dt, p):
    """Force on the rod on a uniform fine grid. Returns (F, T, I_field, Q, F_hyd)."""
    N = x.shape[0]
    F = np.zeros(N)
    Tout = np.zeros(N)
    If = np.zeros(N)
    Qo = np.zeros(N)
    Fh = np.zeros(N)
    A1, Ap, Ar, b, h, L = p[0], p[1], p[2], p[3], p[4], p[5]
    V10 = p[6]
    law = int(p[P_LAW])
    n_hb, ratio, m_pap = p[15], p[16], p[17]
    p0, patm = p[19], p[20]
    Vg0, kappa = p[21], p[22]
    gas_on = p[23] > 0.5
    comp_on = p[24] > 0.5
    K, alpha, nair, pvap = p[25], p[26], p[27], p[28]
    nsub = max(1, int(p[29]))
    fric_on = p[30] > 0.5
    ftype = int(p[31])
    lag_on = p[38] > 0.5
    lag_type = int(p[39])
    ta, tb, vmax_ratio, kdrv = p[40], p[41], p[42], p[43]
    Tamb, Cth, Gth = p[44], p[45], p[46]
    therm_on = p[47] > 0.5
    tlaw = int(p[48])
    btau, bmu = p[49], p[50]
    m_gap = p[51] * p[18] * L * A1 * A1 / (b * h)
    m_rod = p[52]

    # states
    T = Tamb
    i1 = icmd[0]
    i2 = icmd[0]
    z = 0.0
    dp_guess = 0.0
    p1 = p0
    p2 = p0
    nu0, _d = nu_of_p(p0, p0, K, alpha, nair)
    W1 = V10 / nu0
    Wtot = W1 + p[7] / nu0
    Qprev = 0.0
    q = 0.0
    for k in range(N):
        # field seen by the fluid
        if lag_on and k > 0:
            c = icmd[k]
            if lag_type == 0:
                i1 = c + (i1 - c) * math.exp(-dt / ta)
                i2 = i1
            elif lag_type == 1:
                i1 = c + (i1 - c) * math.exp(-dt / ta)
                i2 = i1 + (i2 - i1) * math.exp(-dt / tb)
            else:
                # coil driven by a voltage amplifier with a current loop and a rail:
                # L di/dt = u - R i, u = clip(R c + kdrv R (c - i), +-vmax R I_max);
                # the field follows the coil current through an eddy-current lag tb.
                u = c + kdrv * (c - i1)
                lim = vmax_ratio * p[14]
                u = min(max(u, -lim), lim)
                i1 = u + (i1 - u) * math.exp(-dt / ta)
                i2 = i1 + (i2 - i1) * math.exp(-dt / tb)
            ifield = i2
        else:
            ifield = icmd[k]
        If[k] = ifield
        tau0 = yield_of_current(ifield, p)
        mu = visc_of_current(ifield, p)
        if therm_on:
            tau0 *= thermal_factor(T - Tamb, btau, tlaw)
            mu *= thermal_factor(T - Tamb, bmu, tlaw)
        if law == HERSCHEL_BULKLEY:
            # consistency k with the same stress at a reference rate of 100 1/s
            mu = mu * 100.0 ** (1.0 - n_hb)

        # hydraulics
        if not comp_on:
            Q = A1 * v[k]
            th, va, vb = reversal_split(v[k], a[k], dt)
            if th > 0.0:
                # the rod reverses inside this step: the step's mean force, as the
                # continuous-time rig feeds it to the anti-alias filter (a point sample
                # would put the yield jump on the grid, an error of first order in dt)
                dpa = slit_dp(A1 * va, law, b, h, L, tau0, mu, n_hb, ratio, m_pap, -dp_guess)
                dpb = slit_dp(A1 * vb, law, b, h, L, tau0, mu, n_hb, ratio, m_pap, dp_guess)
                dp = th * dpa + (1.0 - th) * dpb
                dp_guess = dpb
            else:
                dp = slit_dp(Q, law, b, h, L, tau0, mu, n_hb, ratio, m_pap, dp_guess)
                dp_guess = dp
            if gas_on:
                # rod leaving the cylinder (x > 0) frees Ar x: the gas expands
                vg = Vg0 + Ar * x[k]
                p2 = p0 * (Vg0 / vg) ** kappa
                fh = dp * A1 - (p2 - patm) * Ar
            else:
                fh = dp * A1
            fh += m_gap * a[k]
        else:
            # the step carries the chambers from t_k - dt/2 to t_k + dt/2, so the mean flow
            # over it belongs to t_k (the same instant as v[k] = central difference of x)
            hs = dt / nsub
            xa = 0.5 * (x[k - 1] + x[k]) if k > 0 else x[0]
            xb = 0.5 * (x[k] + x[k + 1]) if k + 1 < N else 1.5 * x[k] - 0.5 * x[k - 1]
            for j in range(nsub):
                xs = xa + (xb - xa) * (j + 1) / nsub
                V1 = V10 - A1 * xs
                # backward Euler in the chamber-1 inventory: residual in p1, monotone
                lo, hi = pvap, 1e10
                y = p1
                for it in range(100):
                    if gas_on:
                        nu1, dnu1 = nu_of_p(y, p0, K, alpha, nair)
                        W1n = V1 / nu1
                        p2 = chamber2_pressure(Wtot - W1n, xs, p, K, alpha, p2)
                    else:
                        p2 = p0
                        nu1, dnu1 = nu_of_p(y, p0, K, alpha, nair)
                        W1n = V1 / nu1
                    q, dq = slit_q(y - p2, law, b, h, L, tau0, mu, n_hb, ratio, m_pap)
                    r = W1n - W1 + hs * q
                    dr = -V1 * dnu1 / (nu1 * nu1) + hs * dq
                    if r > 0.0:
                        hi = y
                    else:
                        lo = y
                    if abs(r) <= 1e-13 * W1 or hi - lo <= 1e-9 * hi:
                        break
                    yn = y - r / dr
                    if not (lo < yn < hi):
                        yn = 0.5 * (lo + hi)
                    y = yn
                if y <= pvap * 1.000001:
                    # chamber 1 cavitates: pressure held at vapour pressure
                    y = pvap
                    if gas_on:
                        p2 = chamber2_pressure(Wtot - W1, xs, p, K, alpha, p2)
                    q, dq = slit_q(y - p2, law, b, h, L, tau0, mu, n_hb, ratio, m_pap)
                    W1 = W1 - hs * q
                else:
                    W1 = W1 - hs * q
                p1 = y
            Q = q
            if gas_on:
                fh = (p1 - p2) * A1 - (p2 - patm) * Ar
            else:
                fh = (p1 - p2) * A1
            # pressure that accelerates the gap fluid (inertance rho L/(b h)), reaction on
            # the piston annulus; flow dynamics themselves not fed back (documented)
            if k > 0:
                fh += p[51] * p[18] * L / (b * h) * A1 * (Q - Qprev) / dt
        Qprev = Q
        Qo[k] = Q
        # seal friction
        ff = 0.0
        if fric_on:
            z, ff = friction_step(ftype, z, v[k], a[k], dt, p)
        ftot = fh + ff + m_rod * a[k]
        Fh[k] = fh
        F[k] = ftot
        # lumped heat balance C dT/dt = (dissipated power) - G (T - T_amb)
        Tout[k] = T
        if Cth > 0.0:
            if gas_on:
                pw = (fh + (p2 - patm) * Ar + ff) * v[k]
            else:
                pw = (fh + ff) * v[k]
            T += dt * (pw - Gth * (T - Tamb)) / Cth
    return F, Tout, If, Qo, Fh


P_LAW = P["law"]
