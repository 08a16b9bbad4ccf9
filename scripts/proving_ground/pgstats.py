"""Statistics shared by the proving-ground studies (study.py, estimator_coverage.py,
interval_coverage.py, breakdown.py, misses.py): Wilson intervals and how a diagnosis of
a scenario is scored against what it hides. Standard library only."""
import math


def wilson(k, n, z=1.96):
    """Share k/n with its Wilson score interval: (p, lo, hi); NaNs when n is 0."""
    if n == 0:
        return float("nan"), float("nan"), float("nan")
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    hw = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return p, max(0.0, c - hw), min(1.0, c + hw)


# An effect whose force, after the measurement chain, leaves less than this many σ_F once
# projected onto what a fluid law free at every current absorbs (generate.absorbable_basis:
# per level a Coulomb step and a viscous term, and an offset) is not identifiable as that
# effect: a current-independent Coulomb friction is a higher field-off yield, a slow heating
# within long held levels is a lower yield at each level. The identifiable score counts such
# an effect as optional: neither required nor false when reported.
IDENTIFIABLE_U = 0.5

# The measurement-aware baseline's goal on a null record: its held-out RMS within 15 % of
# the true force noise σ_F.
NULL_BASELINE_WITHIN = 1.15


def null_baseline_ratio(entry):
    """A run's baseline held-out RMS over the scenario's σ_F; None when either is missing."""
    if entry.get("sigma_F") and entry.get("baseline_rmse") is not None:
        return entry["baseline_rmse"] / entry["sigma_F"]
    return None


def score(entry):
    hidden = set(entry["hidden"])
    fnd = set(entry.get("findings", []))
    und = [set(g) for g in entry.get("undecided", [])]
    found = fnd.union(*und) if und else set(fnd)
    false = fnd - hidden
    b, f = entry.get("baseline_rmse"), entry.get("final_rmse")
    gain = bool(fnd) and b is not None and f is not None
    improved = gain and b > 0 and f <= 0.9 * b
    # Near the noise floor a 10 % fall of the RMS is out of reach (a baseline at 1.05 σ_F
    # can fall 5 % at most): the same fall measured on the RMS above σ_F.
    sig = entry.get("sigma_F")
    improved_excess = gain and sig is not None and b > sig and b - f >= 0.1 * (b - sig)
    ua = dict(zip(entry["hidden"], entry.get("u_unabsorbed", [])))
    optional = {e for e in hidden if ua.get(e, float("inf")) < IDENTIFIABLE_U}
    exact_id = (fnd - optional) == (hidden - optional) and not false and not und
    return dict(found=found, detected={e: e in found for e in hidden}, exact=(fnd == hidden and not und),
                exact_identifiable=exact_id, n_optional=len(optional),
                n_false=len(false), false=sorted(false), improved=improved,
                improved_excess=improved_excess, has_finding=bool(fnd))
