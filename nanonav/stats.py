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
import scipy  # its submodules load when first used: an API process starts without them
from numpy.typing import NDArray

DEFAULT_CONFIDENCE = 0.95
# Up to this many non-zero differences without ties, the exact null distribution of the
# signed-rank statistic is used (as scipy's ``method="auto"`` does).
EXACT_MAX_PAIRS = 50
# Up to this many non-zero differences with ties, every one of the 2**n sign patterns is
# enumerated (8,192 at most), which gives the exact distribution given the tied ranks.
PERMUTATION_MAX_PAIRS = 13

# How an interval of a mean is made, by the range of the values (see ``describe``).
STUDENT_T = "student_t"  # any real values: mean +- t sd / sqrt(n)
WILSON = "wilson"  # outcomes that are each 0 or 1: the Wilson score interval
LOGIT_T = "logit_t"  # values in [0, 1]: the t interval on the logit scale, mapped back
LOG_T = "log_t"  # values in [0, inf): the t interval on the log scale, mapped back
POOLED_WILSON = "pooled_wilson"  # shares of trials per seed: Wilson on the pooled trials
INTERVAL_METHODS = {
    STUDENT_T: "Student t interval of the mean, from the sample standard deviation with n - 1 "
    "degrees of freedom",
    WILSON: "Wilson score interval of a proportion of n outcomes, each 0 or 1",
    LOGIT_T: "Student t interval of the mean taken on the logit scale by the delta method "
    "(half-width t sd / (sqrt(n) m (1 - m))) and mapped back, so it stays inside (0, 1)",
    LOG_T: "Student t interval of the mean taken on the log scale by the delta method "
    "(half-width t sd / (sqrt(n) m)) and mapped back, so it stays above 0",
    POOLED_WILSON: "Wilson score interval of the share of all trials of all n seeds (a seed's "
    "value is its share of its trials: robots x worlds, or cells x worlds), with the trials "
    "counted as the seeds' spread allows: their number divided by the design effect (the "
    "variance of the pooled share over seeds, as seeds are the independent units, over the "
    "binomial variance; at least 1) and by (t/z)^2 for n - 1 degrees of freedom, never more "
    "than the trials themselves (Korn and Graubard's interval for clustered samples)",
}
CONFIDENCE_METHOD = (
    f"{DEFAULT_CONFIDENCE:.0%} confidence interval of the mean, made so that it stays in the "
    "metric's range, each named in its 'method': 'student_t' for unbounded metrics (and for mean "
    "paired differences), 'pooled_wilson' for a study's shares of trials (success_rate, "
    "treated_fraction, never_delivered: Wilson on the seeds' pooled trials, their number cut "
    "to what the spread between seeds allows), 'wilson' for 0/1 outcomes, 'logit_t' for other "
    "metrics in [0, 1], 'log_t' for metrics that cannot be negative"
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
    ci_low: float | None  # the interval of the mean; None when n < 2
    ci_high: float | None
    method: str = STUDENT_T  # how the interval was made: a key of INTERVAL_METHODS

    def to_dict(self) -> dict[str, float | int | str | None]:
        return {
            "n": self.n,
            "mean": self.mean,
            "sd": self.sd,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
            "method": self.method,
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
    method: str = STUDENT_T  # the interval's: differences may be of either sign

    def to_dict(self) -> dict[str, float | int | str | None]:
        return {
            "n": self.n,
            "mean_difference": self.mean_difference,
            "sd": self.sd,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
            "p_value": self.p_value,
            "method": self.method,
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


def exact_mean(values: NDArray[np.float64]) -> float:
    """The correctly rounded mean (``math.fsum``): the same bits on every machine, where
    numpy's sums take their order from the processor's vector width."""
    return math.fsum(values.tolist()) / len(values)


def _describe(
    values: NDArray[np.float64], confidence: float, bounds: tuple[float, float] | None = None
) -> Description:
    method = _method(values, bounds)
    n = len(values)
    if n == 0:
        return Description(n=0, mean=None, sd=None, ci_low=None, ci_high=None, method=method)
    if n == 1:
        mean = float(values[0])
        return Description(n=1, mean=mean, sd=None, ci_low=None, ci_high=None, method=method)
    if np.all(values == values[0]):
        # Exactly, not to rounding: the float mean of equal values can differ in its last bit.
        mean = float(values[0])
        if method == WILSON:  # n equal outcomes still leave a proportion uncertain
            low, high = _wilson(mean, n, confidence)
            return Description(n=n, mean=mean, sd=0.0, ci_low=low, ci_high=high, method=method)
        return Description(n=n, mean=mean, sd=0.0, ci_low=mean, ci_high=mean, method=method)
    mean = exact_mean(values)
    sd = float(values.std(ddof=1))
    t = _t_quantile(0.5 + confidence / 2, n - 1)
    if method == WILSON:
        low, high = _wilson(mean, n, confidence)
    elif method == LOGIT_T:
        # logit(m) +- t sd / (sqrt(n) m (1 - m)); 0 < m < 1 since the values differ
        centre = math.log(mean / (1.0 - mean))
        half = t * sd / (math.sqrt(n) * mean * (1.0 - mean))
        low, high = _expit(centre - half), _expit(centre + half)
    elif method == LOG_T:
        # log(m) +- t sd / (sqrt(n) m); m > 0 since the values differ and none is negative
        half = t * sd / (math.sqrt(n) * mean)
        low, high = mean * math.exp(-half), mean * math.exp(half)
    else:
        half = t * sd / math.sqrt(n)
        low, high = mean - half, mean + half
    return Description(n=n, mean=mean, sd=sd, ci_low=low, ci_high=high, method=method)


def _method(values: NDArray[np.float64], bounds: tuple[float, float] | None) -> str:
    """The interval that keeps to ``bounds``: (0, 1), (0, inf) or None for unbounded. Values
    outside the bounds given (which a caller should never pass) get the plain t interval."""
    if bounds == (0.0, 1.0) and np.all((values >= 0.0) & (values <= 1.0)):
        return WILSON if np.all((values == 0.0) | (values == 1.0)) else LOGIT_T
    if bounds == (0.0, math.inf) and np.all(values >= 0.0):
        return LOG_T
    return STUDENT_T


def _expit(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-x)) if x >= 0 else math.exp(x) / (1.0 + math.exp(x))


def _wilson(p: float, n: float, confidence: float) -> tuple[float, float]:
    """The Wilson score interval of a proportion ``p`` of ``n`` outcomes (``n`` may be an
    effective number, not a whole one)."""
    z = float(scipy.stats.norm.ppf(0.5 + confidence / 2))
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def describe(
    values: Sequence[float],
    confidence: float = DEFAULT_CONFIDENCE,
    bounds: tuple[float, float] | None = None,
) -> Description:
    """The mean of ``values`` with a ``confidence`` interval that stays within ``bounds``.

    ``bounds`` is the metric's range: None (unbounded: Student t), ``(0, 1)`` (a proportion:
    Wilson when every value is 0 or 1, else the t interval on the logit scale) or
    ``(0, math.inf)`` (the t interval on the log scale); ``method`` names the one used.
    ``None``, NaN and infinities raise ``ValueError``: the caller decides what a missing value
    means (a failed job, a metric that does not apply) and filters it out. With one value there is
    no spread, so ``sd`` and the interval are ``None``; when every value is the same the interval
    is ``[mean, mean]``, but for 0/1 outcomes, whose Wilson interval says how far n outcomes
    alike still leave the proportion.
    """
    _check_confidence(confidence)
    if bounds not in (None, (0.0, 1.0), (0.0, math.inf)):
        raise ValueError(f"bounds must be None, (0, 1) or (0, inf), not {bounds!r}")
    return _describe(_finite_array(values, "values"), confidence, bounds)


def describe_share(
    shares: Sequence[float],
    trials: Sequence[float],
    confidence: float = DEFAULT_CONFIDENCE,
) -> Description:
    """The share of successes over seeds, each seed's value ``shares[i]`` the share of its
    ``trials[i]`` trials (a success rate over robots x worlds, a treated fraction over cells x
    worlds), with a ``confidence`` interval that respects both what the trials say and that
    only seeds are independent (``POOLED_WILSON``).

    The mean is the pooled share, sum(shares x trials) / sum(trials) (with equal trials, the
    mean of the shares). The interval is Wilson's for that share of ``n_eff`` trials:

    - ``v``, the variance of the pooled share estimated from the spread between seeds (the
      ratio estimator's, ``k / (k - 1) sum((m_i / N)^2 (p_i - p)^2)`` for ``k`` seeds with
      ``m_i`` trials, ``N`` in all): the seeds are the independent units, and the trials of one
      seed (its robots, its worlds, its one learned table) are not independent of each other;
    - ``n_eff = min(N, p (1 - p) / v x (z / t_{k-1})^2)``: the trials counted as many as
      independent ones would give that variance (``N`` over the design effect, which is taken
      as at least 1), then fewer for ``v``'s own uncertainty with few seeds (Korn and
      Graubard, 1998); when the seeds do not differ at all, or the share is 0 or 1, the
      binomial variance is all there is, and ``n_eff`` is ``N``.

    So every seed at 1.0 over 600 trials in all gives [0.994, 1], shorter than one failure in
    600 does, and 200 successes of 200 trials give [0.981, 1], not the [0.72, 1] of ten seeds
    taken as ten trials. Its coverage, checked by simulation in ``tests/test_stats.py``
    (4,000 synthetic studies a case), is 94.4 % to 96.8 % from shares of 0.005 to 0.995, with
    independent trials or seeds and worlds that differ (intra-class correlation up to 0.1), 5
    to 30 seeds; it falls to about 91 % with 10 seeds of strongly clustered trials (0.05)
    near a share of 0.03, where few seeds say little about the spread.
    ``sd`` is the seeds' standard deviation; with one seed there is no interval.
    ``ValueError`` for shares outside [0, 1], trials not positive, or lengths that differ.
    """
    _check_confidence(confidence)
    values = _finite_array(shares, "shares")
    weights = _finite_array(trials, "trials")
    if len(values) != len(weights):
        raise ValueError(f"{len(values)} shares but {len(weights)} trial counts")
    if np.any((values < 0.0) | (values > 1.0)):
        raise ValueError("shares must lie in [0, 1]")
    if np.any(weights <= 0.0):
        raise ValueError("every seed needs at least one trial")
    k = len(values)
    if k == 0:
        return Description(0, None, None, None, None, POOLED_WILSON)
    total = math.fsum(weights.tolist())
    equal = bool(np.all(weights == weights[0]))
    mean = exact_mean(values) if equal else math.fsum((values * weights).tolist()) / total
    mean = min(max(mean, 0.0), 1.0)
    if k == 1:
        return Description(1, mean, None, None, None, POOLED_WILSON)
    sd = 0.0 if np.all(values == values[0]) else float(values.std(ddof=1))
    spread = k / (k - 1) * math.fsum(((weights / total) ** 2 * (values - mean) ** 2).tolist())
    binomial = mean * (1.0 - mean)
    effective = total
    if spread > 0.0 and binomial > 0.0:
        z = float(scipy.stats.norm.ppf(0.5 + confidence / 2))
        t = _t_quantile(0.5 + confidence / 2, k - 1)
        effective = min(total, binomial / spread * (z / t) ** 2)
    low, high = _wilson(mean, effective, confidence)
    return Description(k, mean, sd, low, high, POOLED_WILSON)


@lru_cache(maxsize=1024)
def _t_quantile(p: float, df: int) -> float:
    """Student t quantile; studies ask for the same few thousands of times."""
    return float(scipy.stats.t.ppf(p, df))


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


ADJUSTMENT_METHOD = (
    "Holm's step-down adjustment (p_holm), metric by metric: a metric's family is every "
    "comparison of it the study makes (each compared value against the baseline, at every "
    "combination of the other grid keys, holm_comparisons of them), so that a difference "
    "called resolved at 0.05 by p_holm has at most a 5 % chance that any of its family's is "
    "a false alarm"
)


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

        p = scipy.stats.permutation_test(
            (nonzero,),
            positive_rank_sum,
            permutation_type="samples",
            vectorized=True,
            n_resamples=np.inf,
            alternative="two-sided",
        ).pvalue
    else:
        p = scipy.stats.wilcoxon(nonzero, method="asymptotic").pvalue
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


def pairs_to_resolve(
    mean_difference: float,
    sd: float,
    power: float = 0.8,
    confidence: float = DEFAULT_CONFIDENCE,
    most: int = 100_000,
) -> int | None:
    """How many pairs a paired comparison needs for its Student t interval to exclude zero with
    probability ``power``, if the differences have this mean and standard deviation: the
    smallest n whose two-sided t test at ``1 - confidence`` has that power (noncentral t). A
    small gain measured on few seeds says, with it, how many seeds would settle it.

    ``None`` when no n up to ``most`` does (a zero mean difference never resolves)."""
    _check_confidence(confidence)
    if not 0.0 < power < 1.0:
        raise ValueError(f"power must lie in (0, 1), not {power!r}")
    if not (math.isfinite(mean_difference) and math.isfinite(sd)) or sd < 0.0:
        raise ValueError("mean_difference and sd must be finite, sd not negative")
    if mean_difference == 0.0:
        return None
    if sd == 0.0:
        return 2

    def achieved(n: int) -> float:
        critical = _t_quantile((1.0 + confidence) / 2.0, n - 1)
        shift = abs(mean_difference) * math.sqrt(n) / sd
        nct = scipy.stats.nct
        return float(nct.sf(critical, n - 1, shift) + nct.cdf(-critical, n - 1, shift))

    # the normal approximation brackets the answer; bisection finds the exact n
    z = scipy.stats.norm.ppf((1.0 + confidence) / 2.0) + scipy.stats.norm.ppf(power)
    normal = (z * sd / abs(mean_difference)) ** 2  # the t test needs at least this many
    if normal > most:
        return None
    high = min(most, max(2, math.ceil(normal) + 2))
    while achieved(high) < power:
        if high >= most:
            return None
        high = min(most, high * 2)
    low = 1  # achieved(low) < power, or low is below the smallest n (2)
    while high - low > 1:
        middle = (low + high) // 2
        if middle >= 2 and achieved(middle) >= power:
            high = middle
        else:
            low = middle
    return int(high)


RESOLVING_POWER = 0.8
"""The chance a study's seeds find a difference it calls resolvable: 80 %, the usual design
target."""
RESOLVABLE_METHOD = (
    "the smallest mean difference these seeds find with 80 % chance at two-sided 0.05, given "
    "the differences' spread (the paired t-test's power); a difference d needs about "
    "n * (resolves / d)^2 seeds"
)


def resolvable_difference(
    sd: float | None, n: int, *, alpha: float = 0.05, power: float = RESOLVING_POWER
) -> float | None:
    """The smallest mean paired difference that ``n`` seeds, whose differences spread by
    ``sd``, find at two-sided level ``alpha`` with chance ``power``: the paired t-test's, from
    the noncentral t distribution (the Wilcoxon test the reports use needs about 5 % more seeds
    for normal differences, its asymptotic efficiency being 0.955). A study resolving a smaller
    difference needs more seeds, about ``n * (this / difference)**2``. None with fewer than two
    seeds or no spread to go by."""
    if sd is None or n < 2 or not math.isfinite(sd) or sd <= 0:
        return None
    if not (0 < alpha < 1 and 0 < power < 1):
        raise ValueError("alpha and power must lie strictly between 0 and 1")
    df = n - 1
    critical = float(scipy.stats.t.ppf(1 - alpha / 2, df))

    def short_of_power(effect: float) -> float:
        shift = effect * math.sqrt(n)
        upper = float(scipy.stats.nct.sf(critical, df, shift))
        # the wrong tail: scipy gives NaN where it is far below 1e-30 (large shifts)
        lower = float(scipy.stats.nct.cdf(-critical, df, shift))
        return upper + (lower if math.isfinite(lower) else 0.0) - power

    high = 1.0
    while short_of_power(high) < 0:
        high *= 2.0
    return float(scipy.optimize.brentq(short_of_power, 0.0, high, xtol=1e-10)) * sd


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment of the p-values of a table's ``m`` comparisons (Holm 1979):
    the i-th smallest becomes ``max over j <= i of (m - j + 1) p_(j)``, capped at 1, in the
    order given. A comparison is resolved at family-wise level alpha when its adjusted p-value
    is below alpha: no more than alpha's chance that any of the table's nulls is rejected,
    whatever their dependence, and never less power than Bonferroni's ``m p``.

    NaN, infinities and values outside [0, 1] raise ``ValueError``."""
    raw = _finite_array(p_values, "p_values")
    if np.any((raw < 0.0) | (raw > 1.0)):
        raise ValueError("p_values must lie in [0, 1]")
    m = len(raw)
    order = np.argsort(raw, kind="stable")
    adjusted = np.empty(m)
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (m - rank) * float(raw[index])))
        adjusted[index] = running
    return [float(v) for v in adjusted]
