"""Means with Student t intervals, and paired comparisons of two scenarios run on the same seeds.

A batch study runs every scenario on the same seeds, so a scenario's result on one seed is a
sample and two scenarios give pairs (same seed, same sequence of worlds). Seeds are few (tens, not
thousands), which is why the intervals use Student's t rather than the normal quantile, and why the
test is the Wilcoxon signed-rank test with its exact distribution: simulation metrics are rarely
normal (step counts pile up at the episode limit), and a rank test does not need them to be.

Pure functions on plain numbers: no I/O, and every value returned is a Python ``float``, ``int``
or ``None``, ready for JSON.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy import stats

DEFAULT_CONFIDENCE = 0.95
# Up to this many non-zero differences without ties, the exact null distribution of the
# signed-rank statistic is used (as scipy's ``method="auto"`` does).
EXACT_MAX_PAIRS = 50
# Up to this many non-zero differences with ties, every one of the 2**n sign patterns is
# enumerated (8,192 at most), which gives the exact distribution given the tied ranks.
PERMUTATION_MAX_PAIRS = 13

CONFIDENCE_METHOD = (
    f"{DEFAULT_CONFIDENCE:.0%} Student t confidence interval of the mean (or of the mean paired "
    "difference), from the sample standard deviation with n - 1 degrees of freedom"
)
TEST_METHOD = (
    "Wilcoxon signed-rank test, two-sided, on pairs with the same seed: pairs with zero difference "
    "are dropped, tied differences share their mean rank, and the p-value is exact up to "
    f"{EXACT_MAX_PAIRS} non-zero pairs without ties or {PERMUTATION_MAX_PAIRS} with ties, from the "
    "normal approximation beyond"
)


@dataclass(frozen=True)
class Description:
    """A sample's size, mean, standard deviation and the confidence interval of its mean."""

    n: int
    mean: float | None  # None when n == 0
    sd: float | None  # sample standard deviation (ddof=1); None when n < 2
    ci_low: float | None  # Student t interval of the mean; None when n < 2
    ci_high: float | None

    def to_dict(self) -> dict[str, float | int | None]:
        return {
            "n": self.n,
            "mean": self.mean,
            "sd": self.sd,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
        }


@dataclass(frozen=True)
class PairedComparison:
    """Treatment minus baseline over pairs that share a seed: the mean difference, its
    interval, and the Wilcoxon signed-rank p-value."""

    n: int  # pairs used (all of them, zero differences included)
    mean_difference: float | None  # mean of (treatment - baseline); None when n == 0
    sd: float | None  # sample standard deviation of the differences; None when n < 2
    ci_low: float | None  # Student t interval of the mean difference; None when n < 2
    ci_high: float | None
    p_value: float | None  # Wilcoxon signed-rank, two-sided; None when n < 2

    def to_dict(self) -> dict[str, float | int | None]:
        return {
            "n": self.n,
            "mean_difference": self.mean_difference,
            "sd": self.sd,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
            "p_value": self.p_value,
        }


def _check_confidence(confidence: float) -> None:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie strictly between 0 and 1, not {confidence!r}")


def _finite_array(values: Sequence[float], name: str) -> NDArray[np.float64]:
    """The values as floats; a missing or non-finite value is the caller's to filter out, since
    silently dropping it here would break the pairing by seed."""
    for i, value in enumerate(values):
        if value is None or isinstance(value, bool) or not math.isfinite(value):
            raise ValueError(f"{name}[{i}] is {value!r}; only finite numbers can be summarised")
    return np.asarray(values, dtype=np.float64).reshape(-1)


def _describe(values: NDArray[np.float64], confidence: float) -> Description:
    n = len(values)
    if n == 0:
        return Description(n=0, mean=None, sd=None, ci_low=None, ci_high=None)
    if n == 1:
        return Description(n=1, mean=float(values[0]), sd=None, ci_low=None, ci_high=None)
    if np.all(values == values[0]):
        # Exactly, not to rounding: the float mean of equal values can differ in its last bit.
        mean = float(values[0])
        return Description(n=n, mean=mean, sd=0.0, ci_low=mean, ci_high=mean)
    mean = float(values.mean())
    sd = float(values.std(ddof=1))
    half_width = _t_quantile(0.5 + confidence / 2, n - 1) * sd / math.sqrt(n)
    return Description(n=n, mean=mean, sd=sd, ci_low=mean - half_width, ci_high=mean + half_width)


def describe(values: Sequence[float], confidence: float = DEFAULT_CONFIDENCE) -> Description:
    """The mean of ``values`` with its Student t ``confidence`` interval.

    ``None``, NaN and infinities raise ``ValueError``: the caller decides what a missing value
    means (a failed job, a metric that does not apply) and filters it out. With one value there is
    no spread, so ``sd`` and the interval are ``None``; when every value is the same the interval
    is ``[mean, mean]``.
    """
    _check_confidence(confidence)
    return _describe(_finite_array(values, "values"), confidence)


@lru_cache(maxsize=1024)
def _t_quantile(p: float, df: int) -> float:
    """Student t quantile; studies ask for the same few thousands of times."""
    return float(stats.t.ppf(p, df))


def _average_ranks(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Ranks from 1, ties sharing their mean rank (as ``scipy.stats.rankdata``, without its
    per-call overhead)."""
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    starts_group = np.r_[True, ordered[1:] != ordered[:-1]]
    group = np.cumsum(starts_group) - 1
    starts = np.flatnonzero(starts_group)
    ends = np.r_[starts[1:], len(values)]
    ranks = np.empty(len(values))
    ranks[order] = ((starts + ends + 1) / 2)[group]
    return ranks


def _wilcoxon_p_value(differences: NDArray[np.float64]) -> float:
    """Two-sided p-value of the signed-rank test; see ``paired`` for the choices made.

    The test sees only the signed ranks, so the p-value is computed from them, and for up to
    ``EXACT_MAX_PAIRS`` pairs remembered: a study with many grid points and few seeds asks for
    the same few sign patterns thousands of times."""
    nonzero = differences[differences != 0]
    n = len(nonzero)
    if n == 0:
        return 1.0
    signed = np.sign(nonzero) * _average_ranks(np.abs(nonzero))
    if n <= EXACT_MAX_PAIRS:
        return _signed_rank_p_remembered(tuple(sorted(signed.tolist())))
    return _signed_rank_p(signed)


@lru_cache(maxsize=EXACT_MAX_PAIRS)
def _signed_rank_counts(n: int) -> NDArray[np.float64]:
    """How many of the 2**n sign patterns of the ranks 1..n give each sum of positive ranks
    (0 .. n(n+1)/2): the exact null distribution of the statistic without ties."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for rank in range(1, n + 1):
        counts[rank:] = counts[rank:] + counts[:-rank].copy()
    return counts


@lru_cache(maxsize=8192)
def _signed_rank_p_remembered(signed: tuple[float, ...]) -> float:
    return _signed_rank_p(np.array(signed))


def _signed_rank_p(nonzero: NDArray[np.float64]) -> float:
    """The p-value of non-zero signed ranks (ties share their mean rank)."""
    n = len(nonzero)
    ranks = np.abs(nonzero)
    tied = len(np.unique(ranks)) < n
    if not tied and n <= EXACT_MAX_PAIRS:
        positive = int(ranks[nonzero > 0].sum())
        counts = _signed_rank_counts(n)
        below = counts[: positive + 1].sum()
        above = counts[positive:].sum()
        p = 2 * min(below, above) / counts.sum()
    elif tied and n <= PERMUTATION_MAX_PAIRS:
        # What scipy's method="auto" does here, with a statistic that takes a whole batch of sign
        # patterns at once: about thirty times faster than scipy's own loop over them at 13 pairs.
        def positive_rank_sum(signed: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
            total: NDArray[np.float64] = np.sum(np.where(signed > 0, ranks, 0.0), axis=axis)
            return total

        p = stats.permutation_test(
            (nonzero,),
            positive_rank_sum,
            permutation_type="samples",
            vectorized=True,
            n_resamples=np.inf,
            alternative="two-sided",
        ).pvalue
    else:
        p = stats.wilcoxon(nonzero, method="asymptotic").pvalue
    return min(float(p), 1.0)


def paired(
    treatment: Sequence[float],
    baseline: Sequence[float],
    confidence: float = DEFAULT_CONFIDENCE,
) -> PairedComparison:
    """How much ``treatment`` differs from ``baseline``, pair by pair (position i of both is the
    same seed): the mean of ``treatment - baseline`` with its Student t interval, and the
    two-sided Wilcoxon signed-rank p-value.

    Zero differences and ties, deliberately:

    - A pair with zero difference (both scenarios scored the same on that seed, e.g. both hit
      the step limit) says nothing about which is better and is dropped from the test, as
      Wilcoxon proposed (scipy's ``zero_method="wilcox"``, its default). It still counts in
      ``n``, the mean difference and the interval. If every difference is zero, ``p_value`` is
      1.0.
    - Differences with equal absolute value share the mean of their ranks.
    - With the ``m`` non-zero differences left: without ties and ``m <= 50``, the exact null
      distribution (``scipy.stats.wilcoxon(method="exact")``); with ties and ``m <= 13``, the
      exact distribution given those ranks, by enumerating all ``2**m`` sign patterns (what
      ``scipy.stats.wilcoxon(method="auto")`` does, computed in one vectorised pass); beyond,
      the normal approximation with scipy's tie correction and no continuity correction
      (``method="asymptotic"``). So with few pairs the p-value is exact, and it cannot go below
      ``2 / 2**m``: five pairs that all agree give 0.0625, never "significant" at 0.05.

    The choice is made on the non-zero differences, so it can differ from scipy's own
    ``method="auto"``, which counts the zeros when it compares the sample size with 50 and 13.
    Differences are taken as computed in floating point, not rounded: two differences that
    would be equal in exact arithmetic but differ in their last bit are not tied.

    ``None``, NaN, infinities and unequal lengths raise ``ValueError``. ``p_value`` is ``None``
    with fewer than two pairs.
    """
    _check_confidence(confidence)
    treated = _finite_array(treatment, "treatment")
    base = _finite_array(baseline, "baseline")
    if len(treated) != len(base):
        raise ValueError(
            f"treatment has {len(treated)} values and baseline {len(base)}; "
            "they must pair up seed by seed"
        )
    differences = treated - base
    summary = _describe(differences, confidence)
    return PairedComparison(
        n=summary.n,
        mean_difference=summary.mean,
        sd=summary.sd,
        ci_low=summary.ci_low,
        ci_high=summary.ci_high,
        p_value=_wilcoxon_p_value(differences) if summary.n >= 2 else None,
    )
