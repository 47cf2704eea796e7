"""The material damping eta that gives gvsjax's soft arm the decay of DisMech-RL's Elastica arm.

Choi and Tong's soft-arm RL benchmark (arXiv:2511.06667) runs its reference arm in PyElastica 0.2.4: 20
elements, 1 m, radius 5 cm, E = 10 MPa, G = E/3, 1000 kg/m^3, clamped along +z, position Verlet at 2e-4 s,
``straight_rod(..., nu=10)``: a force -nu l_e v on each element (its mean node velocity, shared by its two
nodes) and a torque -nu l_e omega, explicit in the step. PyElastica 1.0's ``AnalyticalLinearDamper`` instead
scales the rates by exp(-rate dt) after each step; its physical protocol (rate = constant / nodal mass, and
constant / element inertia J_e) has the same law with translational_damping_constant = nu x each node's share
of element length and rotational = nu l_e. But the angular rate nu / (rho I) = 2000 /s has rate x dt = 0.41,
where the factor damps (e^x - 1) / x = 1.23 times the explicit torque (the arm decays 22% fast), so this script
sets rotational_damping_constant = (J_e / dt) ln(1 + nu l_e dt / J_e), which restores 0.2.4's law. That torque
term, not the force (alone: nu / (2 rho A) = 0.64 /s on every mode), makes most of the decay.

Measured: each simulator released from rest in the Euler-Bernoulli cantilever's mode-1 (then mode-2) shape,
1 cm at the tip, no gravity; the tip's lateral displacement fit by a sum of damped sinusoids and exponentials,
one per mode present. gvsjax: ``gv.soft_arm`` (bending order 4, torsion 0, stretch 1), ars443 at 2 ms. Its
section damping is 3 eta / E times its stiffness, so an underdamped mode decays at 3 eta omega^2 / (2 E): eta by
a secant on simulated decay rates. Cross-checks: 0.2.4's law as a 1.0 forcing, and 0.2.4 itself in a subprocess
when PYELASTICA_024 names its unpacked source (``pip download pyelastica==0.2.4 --no-deps``, untar).

    PYELASTICA_024=/tmp/pyelastica-0.2.4 python experiments/transfer/dismech_damping.py   # ~1.5 min on 2 cores

Writes benchmarks/dismech_damping.json.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
from scipy.optimize import curve_fit

import gvsjax as gv  # configures JAX before any computation

L, R, E, RHO, NU, N_EL, DT = 1.0, 0.05, 1e7, 1000.0, 10.0, 20, 2e-4
A, I = np.pi * R**2, np.pi * R**4 / 4
AMP = 0.01  # m at the tip: linear regime
BETA = (1.8751040687, 4.6940911330)  # cantilever eigenvalues beta_j L
T_MODE = (3.0, 1.0)  # s simulated per mode: by then mode 1 is down to ~1e-5 of its start
OMEGA_EB = [b**2 * np.sqrt(E * I / (RHO * A * L**4)) for b in BETA]
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def mode_shape(j: int, s):
    """Cantilever mode j's deflection, slope and curvature, normalized to 1 at the tip."""
    b, bl = BETA[j] / L, BETA[j]
    c = (np.cosh(bl) + np.cos(bl)) / (np.sinh(bl) + np.sin(bl))
    ch, co, sh, si = np.cosh(b * s), np.cos(b * s), np.sinh(b * s), np.sin(b * s)
    tip = np.cosh(bl) - np.cos(bl) - c * (np.sinh(bl) - np.sin(bl))
    return (ch - co - c * (sh - si)) / tip, b * (sh + si - c * (ch - co)) / tip, b * b * (ch + co - c * (sh + si)) / tip


def fit(t, y, guess):
    """Least squares by a sum of terms: (sigma, omega) a e^(-sigma t) cos(omega t + phi); (mu,) b e^(-mu t)."""
    sizes = [2 * len(g) for g in guess]

    def model(t, *p):
        out, k = 0.0, 0
        for n in sizes:
            out = out + p[k] * np.exp(-p[k + 1] * t) * (np.cos(p[k + 2] * t + p[k + 3]) if n == 4 else 1.0)
            k += n
        return out
    p0 = [x for g in guess for x in (y[0] / len(guess), g[0], *((g[1], 0.0) if len(g) == 2 else ()))]
    p, _ = curve_fit(model, t, y, p0=p0, maxfev=100000)
    ks = np.cumsum([0] + sizes[:-1])
    terms = [{"sigma": p[k + 1]} | ({"omega": abs(p[k + 2])} if n == 4 else {}) for k, n in zip(ks, sizes)]
    return terms, float(np.sqrt(np.mean((y - model(t, *p)) ** 2)) / np.abs(y).max())


# ---------------------------------------------------------------- PyElastica (1.0, or 0.2.4 in the subprocess)

def elastica_tip(damping: str, j: int):
    """Times and tip x of the arm released from mode j's shape. damping: none, damper, uncorrected, translational,
    law, rayleigh (PyElastica 1.0), native (0.2.4)."""
    import elastica as ea
    legacy = damping == "native"

    class LawOf024(ea.NoForces):  # 0.2.4's dissipation, as it entered the internal forces
        def apply_forces(self, system, time=0.0):
            v = system.velocity_collection
            f = NU * 0.5 * (v[:, :-1] + v[:, 1:]) * system.lengths
            system.external_forces[:, :-1] -= 0.5 * f
            system.external_forces[:, 1:] -= 0.5 * f

        def apply_torques(self, system, time=0.0):
            system.external_torques -= NU * system.omega_collection * system.lengths

    mixins = (ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.CallBacks) + (() if legacy else (ea.Damping,))
    sim = type("Sim", mixins, {})()
    rod = ea.CosseratRod.straight_rod(n_elements=N_EL, start=np.zeros(3), direction=np.array([0.0, 0.0, 1.0]),
                                      normal=np.array([1.0, 0.0, 0.0]), base_length=L, base_radius=R, density=RHO,
                                      youngs_modulus=E, shear_modulus=E / 3.0, **({"nu": NU} if legacy else {}))
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    if damping in ("damper", "uncorrected", "translational"):
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, time_step=DT, **damper_settings(damping))
    elif damping == "law":
        sim.add_forcing_to(rod).using(LawOf024)
    elif damping == "rayleigh":
        sim.dampen(rod).using(ea.RayleighDissipation, damping_constant=NU)
    # mode j's shape: element k turned by the slope at its middle (no shear, no stretch); element 0 is clamped
    dl = L / N_EL
    theta = AMP * mode_shape(j, (np.arange(N_EL) + 0.5) * dl)[1]
    theta[0] = 0.0
    rod.position_collection[0, 1:] = np.cumsum(dl * np.sin(theta))
    rod.position_collection[2, 1:] = np.cumsum(dl * np.cos(theta))
    c, s, o = np.cos(theta), np.sin(theta), np.zeros(N_EL)
    rod.director_collection[:] = np.array([[c, o, -s], [o, o + 1.0, o], [s, o, c]])  # rows d1, d2, d3
    rec = []

    class Tip(ea.CallBackBaseClass):
        def make_callback(self, system, time, current_step):
            if current_step % 10 == 0:
                rec.append((time, system.position_collection[0, -1]))

    sim.collect_diagnostics(rod).using(Tip)
    sim.finalize()
    from elastica.timestepper import integrate  # where both versions have it
    integrate(ea.PositionVerlet(), sim, T_MODE[j], int(round(T_MODE[j] / DT)), progress_bar=False)
    return np.array([r[0] for r in rec]), np.array([r[1] for r in rec])


def damper_settings(kind: str = "damper") -> dict:
    dl = L / N_EL
    J = RHO * np.array([I, I, 2 * I])[:, None] * dl * np.ones(N_EL)  # element inertias (3, n_elem)
    rot = {"damper": np.log1p(NU * dl * DT / J) * J / DT, "uncorrected": NU * dl * J / J, "translational": 0 * J}[kind]
    return {"translational_damping_constant": NU * dl * np.r_[0.5, np.ones(N_EL - 1), 0.5],
            "rotational_damping_constant": rot}


def elastica_modes(damping: str) -> dict:
    """Mode-1 and mode-2 decay rate and damped frequency, each from the run started in its shape."""
    out = {}
    for j in (0, 1):
        t, y = elastica_tip(damping, j)
        s0 = 0.0 if damping in ("none", "rayleigh") else [1.0, 5.0][j]
        terms, rms = fit(t, y, [(s0, OMEGA_EB[0]), (s0, OMEGA_EB[1])])
        out[f"mode{j + 1}"] = {"sigma": terms[j]["sigma"], "omega": terms[j]["omega"], "fit_rms_rel": rms}
        if damping in ("uncorrected", "rayleigh"):
            break  # mode 1 is enough to show the offset
    return out


# ---------------------------------------------------------------- gvsjax

def gvsjax_arm(eta: float):
    return gv.soft_arm(youngs_modulus=E, density=RHO, poisson=0.5, gravity=0.0, damping=eta, bending_order=4,
                       torsion_order=0, stretch_order=1, n_gauss=5)


def gvsjax_q0(arm, j: int) -> np.ndarray:
    """Mode j's curvature projected on the Legendre bending basis about the local z (lateral along world +x)."""
    X, w = np.polynomial.legendre.leggauss(40)
    X, w = 0.5 * (X + 1.0), 0.5 * w  # Gauss on [0, 1]
    f = AMP * mode_shape(j, X * L)[2] * L  # the basis's angular rows carry a 1/L
    q = np.zeros(arm.n_dofs)  # (torsion 1, bend_y 5, bend_z 5, stretch 2) Legendre coefficients
    q[6:11] = [(2 * k + 1) * np.sum(w * f * np.polynomial.legendre.legval(2 * X - 1, np.eye(5)[k])) for k in range(5)]
    return q


def gvsjax_tip(eta: float, j: int):
    arm = gvsjax_arm(eta)
    tr = gv.simulate(arm, 3.0, 2e-3, q0=gvsjax_q0(arm, j), integrator="ars443", save_every=1)  # one program for all
    t, y = np.asarray(tr.t), np.asarray(tr.tip)[:, 0]
    return (t, y) if j == 0 else (t[t <= T_MODE[1]], y[t <= T_MODE[1]])


def gvsjax_sigma1(eta: float, omega_guess: float) -> tuple[float, float, float]:
    t, y = gvsjax_tip(eta, 0)
    sig = 1.5 * eta * omega_guess**2 / E
    terms, rms = fit(t, y, [(sig, np.sqrt(max(omega_guess**2 - sig**2, 1.0))), (E / (3 * eta),)])
    return terms[0]["sigma"], terms[0]["omega"], rms


def gvsjax_linear(eta: float) -> tuple[np.ndarray, np.ndarray]:
    """Undamped frequencies and the eigenvalues of the arm linearized about straight."""
    import jax.numpy as jnp
    import scipy.linalg as sl

    from gvsjax.core.dynamics import full_matrix
    arm = gvsjax_arm(eta)
    n = arm.n_dofs
    K, D = (np.asarray(full_matrix(X, n)) for X in gv.stiffness_and_damping(arm))
    M, _ = gv.mass_and_forces(arm, [jnp.float64(0.0)] * n, [jnp.float64(0.0)] * n, tension=[0.0] * len(arm.tendons))
    M = np.asarray(full_matrix(M, n))
    lam = np.linalg.eigvals(np.block([[0 * K, np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]]))
    return np.sqrt(sl.eigh(K, M, eigvals_only=True)), lam


def main() -> None:
    if "--child" in sys.argv:  # runs under pyelastica 0.2.4
        print(json.dumps(elastica_modes("native")))
        return
    from importlib.metadata import version
    pe = {"version": version("pyelastica"), "n_elements": N_EL, "dt": DT, "integrator": "PositionVerlet",
          "clamp": "OneEndFixedBC (node 0, director 0)",
          "damper": {"class": "AnalyticalLinearDamper", "time_step": DT}
          | {k: v.tolist() for k, v in damper_settings().items()},
          "damper_formula": "translational_damping_constant = nu x node's share of element length (nu dl / 2 at the "
                            "ends, nu dl inside); rotational_damping_constant = (J_e / dt) ln(1 + nu l_e dt / J_e) "
                            "per axis, J_e = rho (I, I, 2I) l_e"}
    pe |= elastica_modes("damper")
    pe["undamped"] = elastica_modes("none")
    pe["variants"] = {"0.2.4 force law as a 1.0 forcing": elastica_modes("law"),
                      "physical protocol, rotational = nu l_e (uncorrected)": elastica_modes("uncorrected"),
                      "translational part alone (rotational = 0)": elastica_modes("translational"),
                      # it adds forces after the step's dynamics, and they are zeroed before the next: no damping
                      "RayleighDissipation(damping_constant=nu)": elastica_modes("rayleigh")}
    src = os.environ.get("PYELASTICA_024")
    if src:
        env = dict(os.environ, PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
        r = subprocess.run([sys.executable, os.path.abspath(__file__), "--child"], env=env, check=True,
                           capture_output=True, text=True)
        pe["variants"]["pyelastica 0.2.4, straight_rod(nu=10)"] = json.loads(r.stdout.strip().splitlines()[-1])
    for k, v in [("chosen damper", pe), ("undamped", pe["undamped"])] + list(pe["variants"].items()):
        print(f"PyElastica, {k}: " + ", ".join(f"{m}: sigma {v[m]['sigma']:.4f} /s, omega {v[m]['omega']:.3f} rad/s"
                                               for m in ("mode1", "mode2") if m in v), flush=True)
    target = pe["mode1"]["sigma"]

    # gvsjax: from the paper arm's 1e5 Pa s, a step proportional to the decay rate, then a secant step
    w0, _ = gvsjax_linear(0.0)  # w0[0:2] the two bending planes' mode 1, w0[2:4] their mode 2
    etas, sigmas = [1e5], []
    for i in range(3):
        sigmas.append(gvsjax_sigma1(etas[-1], w0[0]))
        print(f"gvsjax eta {etas[-1]:.6g} Pa s: sigma1 {sigmas[-1][0]:.4f} /s, omega1 {sigmas[-1][1]:.3f} rad/s",
              flush=True)
        pts = [(0.0, 0.0), (etas[0], sigmas[0][0])] if i == 0 else [(e, x[0]) for e, x in zip(etas[-2:], sigmas[-2:])]
        (e0, s0), (e1, s1) = pts
        etas.append(e1 + (target - s1) * (e1 - e0) / (s1 - s0))
    eta = float(etas[-2])  # the last simulated eta
    sigma1, omega1, rms1 = sigmas[-1]
    _, lam = gvsjax_linear(eta)
    lam1 = min((z for z in lam if z.imag > 0), key=abs)
    # mode 2: overdamped at this eta (zeta2 > 1) so it relaxes as two exponentials, plus some mode 1
    z2 = 1.5 * eta * w0[2] / E
    slow, fast = w0[2] * (z2 - np.sqrt(max(z2**2 - 1.0, 0.0))), w0[2] * (z2 + np.sqrt(max(z2**2 - 1.0, 0.0)))
    t, y = gvsjax_tip(eta, 1)
    terms, rms2 = fit(t, y, [(sigma1, omega1), (slow,), (fast,)])
    gvs = {"settings": "gv.soft_arm(youngs_modulus=1e7, density=1000, poisson=0.5, gravity=0, damping=eta,"
                                   " bending_order=4, torsion_order=0, stretch_order=1, n_gauss=5); ars443, dt 2e-3",
           "root_find": [{"eta": e, "sigma1": s[0]} for e, s in zip(etas, sigmas)],
           "mode1": {"sigma": sigma1, "omega": omega1, "fit_rms_rel": rms1},
           "mode2": {"zeta": z2, "modal_c_over_2m": 1.5 * eta * w0[2] ** 2 / E, "sigma_slow": terms[1]["sigma"],
                     "sigma_fast": terms[2]["sigma"], "fit_rms_rel": rms2},
           "undamped": {"mode1": {"omega": w0[0]}, "mode2": {"omega": w0[2]}},
           "linearized": {"mode1_eigenvalue": [lam1.real, lam1.imag], "mode2_roots": [-slow, -fast],
                          "higher_modes_limit": -E / (3 * eta)}}
    print(f"gvsjax eta {eta:.5g} Pa s: sigma1 {sigma1:.4f} /s (target {target:.4f}); mode 2 zeta {z2:.2f}, relaxes at "
          f"{terms[1]['sigma']:.2f} and {terms[2]['sigma']:.1f} /s (linear theory {slow:.2f}, {fast:.1f})")
    sig2, zeta = pe["mode2"]["sigma"], lambda m: m["sigma"] / np.hypot(m["sigma"], m["omega"])
    out = {"paper": "Choi and Tong 2025, arXiv:2511.06667 (DisMech-RL soft arm, Elastica reference)",
           "case": {"L": L, "radius": R, "E": E, "G": E / 3, "density": RHO, "nu": NU, "gravity": 0.0,
                    "tip_amplitude": AMP, "initial": "Euler-Bernoulli cantilever mode shape, released from rest"},
           "euler_bernoulli_omega": {"mode1": OMEGA_EB[0], "mode2": OMEGA_EB[1]},
           "eta": eta, "pyelastica": pe, "gvsjax": gvs,
           "mode2_comparison": {"pyelastica_zeta": [zeta(pe["mode1"]), zeta(pe["mode2"])],
                                "gvsjax_zeta": [-lam1.real / abs(lam1), z2],
                                "pyelastica_sigma2_over_sigma1": sig2 / target,
                                "gvsjax_c_over_2m_ratio": gvs["mode2"]["modal_c_over_2m"] / sigma1,
                                "gvsjax_slow_relaxation_over_pyelastica_sigma2": terms[1]["sigma"] / sig2}}
    with open(os.path.join(ROOT, "benchmarks", "dismech_damping.json"), "w") as f:
        json.dump(out, f, indent=2, default=float)


if __name__ == "__main__":
    main()
