"""Statistics shared by the proving-ground studies (study.py, estimator_coverage.py,
interval_coverage.py). Standard library only."""
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
