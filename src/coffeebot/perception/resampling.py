"""Resampling a particle set: low variance, with KLD-sampling's adaptive count (Fox 2003).

Fox's KLD sampling draws particles one by one and stops once the count suffices for the
number ``k`` of histogram bins they occupy: enough that, with probability ``quantile``, the
Kullback-Leibler distance between the sample and the true posterior stays below ``error``.
Here that count is found on a randomly ordered low-variance draw (so any prefix is a fair
sample), and the particles are then drawn again with the low-variance sampler at exactly
that count (Probabilistic Robotics, table 4.4): one uniform number, evenly spaced pointers,
the least sampling noise for the count.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np


def low_variance_indices(weights: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` indices drawn in proportion to ``weights`` (normalised or not)."""
    cumulative = np.cumsum(weights)
    cumulative /= cumulative[-1]
    pointers = (rng.random() + np.arange(count)) / count
    return np.minimum(np.searchsorted(cumulative, pointers, side="left"), len(weights) - 1)


def kld_count(bins: np.ndarray | int, error: float, quantile: float) -> np.ndarray:
    """Fox's bound: particles needed for ``bins`` occupied histogram bins (1 for one bin)."""
    k = np.maximum(np.asarray(bins, dtype=float), 1.0)
    z = NormalDist().inv_cdf(quantile)
    a = 2.0 / (9.0 * np.maximum(k - 1.0, 1.0))
    bound = (k - 1.0) / (2.0 * error) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(k > 1, np.ceil(bound), 1.0)


def bin_keys(particles: np.ndarray, bin_mm: float, bin_rad: float) -> np.ndarray:
    """One integer per particle naming its (x, y, heading) histogram bin."""
    ix = np.floor(particles[:, 0] / bin_mm).astype(np.int64)
    iy = np.floor(particles[:, 1] / bin_mm).astype(np.int64)
    ih = np.floor(np.mod(particles[:, 2], 2 * math.pi) / bin_rad).astype(np.int64)
    return (ix * 1_000_003 + iy) * 1_009 + ih


def adaptive_count(
    particles: np.ndarray,
    weights: np.ndarray,
    *,
    minimum: int,
    maximum: int,
    bin_mm: float,
    bin_rad: float,
    error: float,
    quantile: float,
    rng: np.random.Generator,
) -> int:
    """How many particles the posterior these weighted particles describe needs.

    The draw starts at twice the current count (or ``minimum``) and only goes to ``maximum``
    when that does not suffice: a converged filter pays for a few hundred, not thousands."""
    trial = min(maximum, max(minimum, 2 * len(particles)))
    while True:
        draw = particles[low_variance_indices(weights, trial, rng)]
        keys = bin_keys(draw[rng.permutation(trial)], bin_mm, bin_rad)
        _, first = np.unique(keys, return_index=True)
        new_bin = np.zeros(trial, dtype=bool)
        new_bin[first] = True
        needed = kld_count(np.cumsum(new_bin), error, quantile)
        drawn = np.arange(1, trial + 1)
        enough = np.flatnonzero((drawn >= needed) & (drawn >= minimum))
        if len(enough):
            return int(drawn[enough[0]])
        if trial >= maximum:
            return maximum
        trial = maximum


def effective_sample_size(weights: np.ndarray) -> float:
    """1 / sum(w^2) of the normalised weights: how many particles really carry the estimate."""
    total = float(weights.sum())
    if total <= 0:
        return 0.0
    w = weights / total
    return float(1.0 / np.dot(w, w))
