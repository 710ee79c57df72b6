"""Subset simulation (Au & Beck 2001, Probabilistic Engineering Mechanics 16(4), 263-277): the
probability of a rare event as a product of conditional probabilities of about ``p0``.

The event is ``margin <= 0`` of a limit state over independent standard-normal inputs ``z``.
Level 0 draws ``per_level`` samples from the prior. Each next level takes the ``chains = p0
per_level`` samples of lowest margin as seeds, sets the level's threshold ``b`` half-way between
the chains-th and the (chains + 1)-th lowest margin, and grows each seed into a Markov chain of
``steps = per_level / chains`` states whose stationary law is the prior conditional on ``margin <=
b``: a proposal (component-wise modified Metropolis, Au & Beck sec. 3, or preconditioned
Crank-Nicolson, Cotter et al. 2013) is accepted where its margin is ``<= b`` (and it lies in the
inputs' support), else the chain stays. Once ``chains`` or more samples of a level fail (``margin
<= 0``), P = p0^L * (failing fraction of level L).

The same code serves the pure tests (a vectorised limit state, :func:`subset_simulation`) and a
flown campaign (``refexmc.campaign.rare_event``): ``evaluate(level, step, z)`` returns the margins
of a round's samples, whoever computes them. Every random number comes from a generator keyed by
(seed, level, step), so a round's proposals are the same whatever evaluates them, in whatever
order; normals are ``ndtri`` of uniforms and the Metropolis ratio is a correctly rounded exp
(``refexmc.crmath``), as the campaign's own draws.

Uncertainty (Au & Beck eq. 24-29): each level's c.o.v. ``delta_i^2 = (1 - p_i) / (N p_i) (1 +
gamma_i)``, ``gamma_i`` from the correlation of the failure indicator along the chains (level 0:
independent samples, gamma 0); the estimate's c.o.v. is ``sqrt(sum delta_i^2)``, which takes the
levels as uncorrelated (Au & Beck's own approximation; tests/test_subset.py measures what it
covers). The 95 % interval is lognormal: ``P exp(+-1.96 sqrt(ln(1 + delta^2)))``, never below 0.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from refexmc import crmath

PROPOSALS = ("mma", "pcn")
DEFAULT_SPREAD = {"mma": 1.0, "pcn": 0.6}  # MMA: proposal sigma per component (Au & Beck sec. 5); pCN: step s
PROPOSAL_KEY = 0x5B5E7  # the keyed stream of the proposals: SeedSequence([seed, PROPOSAL_KEY, level, step])
Z95 = 1.959963984540054  # the two-sided 95 % normal quantile


@dataclass(frozen=True)
class Design:
    """A subset-simulation study: samples per level, conditional probability p0, level limit, proposal
    (what makes one unusable: refexmc.config.rare_event.design_problem)."""

    per_level: int = 1000
    p0: float = 0.1
    max_levels: int = 10
    proposal: str = "pcn"
    spread: float | None = None  # None: DEFAULT_SPREAD of the proposal

    @property
    def chains(self):
        return int(round(self.p0 * self.per_level))

    @property
    def steps(self):
        """States per chain, its seed included."""
        return self.per_level // self.chains

    @property
    def step_size(self):
        return DEFAULT_SPREAD[self.proposal] if self.spread is None else self.spread


def run_index(design, level, step, chain):
    """The sample's index in the study (a campaign's run id): level 0 sample ``chain`` is ``chain``;
    a later level's step ``step >= 1`` of chain ``chain`` follows every earlier round."""
    if level == 0:
        return chain
    rounds = (level - 1) * (design.steps - 1) + (step - 1)
    return design.per_level + rounds * design.chains + chain


def round_rng(seed, level, step):
    """The generator of round (level, step)'s random numbers: keyed, never the order of evaluation."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), PROPOSAL_KEY, int(level), int(step)]))


def standard_normals(rng, shape):
    """Standard normals as ndtri of uniforms (the campaign's draws do the same: distributions.transform_rows)."""
    from scipy import special

    return special.ndtri(np.clip(rng.random(shape), 1e-300, 1.0 - 2.0**-53))


def level0_normals(seed, per_level, dims):
    """The prior samples of a pure study's level 0."""
    return standard_normals(round_rng(seed, 0, 0), (per_level, dims))


def propose(design, z, rng):
    """Candidates for chains at ``z`` (chains x dims), from ``rng``.

    MMA (Au & Beck eq. 16-18): per component, xi = z + s eps, kept with probability
    min(1, phi(xi) / phi(z)), else z. pCN: sqrt(1 - s^2) z + s eps (prior-reversible).
    """
    s = design.step_size
    eps = standard_normals(rng, z.shape)
    if design.proposal == "pcn":
        return math.sqrt(1.0 - s * s) * z + s * eps
    u = rng.random(z.shape)
    xi = z + s * eps
    log_ratio = 0.5 * (z * z - xi * xi)
    accept = log_ratio >= 0.0
    uphill = ~accept
    accept[uphill] = u[uphill] < crmath.exp(log_ratio[uphill])
    return np.where(accept, xi, z)


@dataclass
class Level:
    """One level: its threshold (None for level 0), conditional probability and chain correlation."""

    threshold: float | None
    probability: float = math.nan  # P(margin <= next threshold | this level) estimated from its samples
    gamma: float = 0.0
    cov: float = math.nan
    flights: int = 0
    proposals: int = 0
    accepted: int = 0
    outside_support: int = 0


@dataclass
class Study:
    """The result: P, its c.o.v. and interval, every level, and the samples of the last level."""

    design: Design
    levels: list = field(default_factory=list)
    probability: float = math.nan
    cov: float = math.nan
    ci95: tuple = (math.nan, math.nan)
    stopped: str = ""  # "event reached" (>= chains samples fail) or "max_levels" (P from fewer failures, or none)
    z: np.ndarray | None = None  # last level's samples (N x dims)
    margins: np.ndarray | None = None
    index: np.ndarray | None = None  # their run index (the chain state's flight)

    @property
    def flights(self):
        return sum(level.flights for level in self.levels)


def _chain_gamma(indicator, chains, steps, p):
    """Au & Beck eq. 27-29: gamma = 2 sum_k (1 - k/steps) rho(k) of the indicator along the chains
    (``indicator`` chains x steps)."""
    if p <= 0.0 or p >= 1.0 or steps < 2:
        return 0.0
    r0 = p * (1.0 - p)
    gamma = 0.0
    for k in range(1, steps):
        rk = float(np.sum(indicator[:, : steps - k] * indicator[:, k:])) / (chains * (steps - k)) - p * p
        gamma += 2.0 * (1.0 - k / steps) * (rk / r0)
    return max(gamma, 0.0)


def _seeds(margins, chains):
    """(threshold, indices of the ``chains`` lowest margins): stable order, so ties keep the sample order."""
    order = np.argsort(margins, kind="stable")
    low, next_up = margins[order[chains - 1]], margins[order[chains]]
    threshold = 0.5 * (low + next_up) if math.isfinite(low) and math.isfinite(next_up) else low
    return threshold, order[:chains]


def subset_simulation(design, seed, dims, evaluate, z0=None, in_support=None):
    """Run a study; ``evaluate(level, step, z, index)`` gives the margins of samples ``z`` (rows) whose
    run indices are ``index``; ``in_support(z)`` (optional) is False for proposals outside the
    inputs' support (rejected, not evaluated). ``z0``: level 0's samples (default
    :func:`level0_normals`). Returns a :class:`Study`."""
    n, chains, steps = design.per_level, design.chains, design.steps
    z = level0_normals(seed, n, dims) if z0 is None else np.asarray(z0, dtype=float)
    index = np.arange(n)
    margins = np.asarray(evaluate(0, 0, z, index), dtype=float)
    margins = np.where(np.isnan(margins), -np.inf, margins)  # no value (an errored run): failing
    study = Study(design)
    study.levels.append(Level(None, flights=n))
    indicator_shape = None
    product = 1.0
    cov2 = 0.0
    level = 0
    while True:
        failing = int(np.sum(margins <= 0.0))
        current = study.levels[-1]
        if failing >= chains or level + 1 >= design.max_levels:
            current.probability = failing / n
            current.gamma = _gamma_of(margins <= 0.0, indicator_shape, current.probability)
            study.stopped = "event reached" if failing >= chains else "max_levels"
            break
        threshold, seeds = _seeds(margins, chains)
        current.probability = chains / n
        current.gamma = _gamma_of(margins <= threshold, indicator_shape, current.probability)
        current.cov = _level_cov(current.probability, n, current.gamma)
        level += 1
        state_z, state_margin, state_index = z[seeds], margins[seeds], index[seeds]
        all_z = np.empty((chains, steps, z.shape[1]))
        all_margin = np.empty((chains, steps))
        all_index = np.empty((chains, steps), dtype=np.int64)
        all_z[:, 0], all_margin[:, 0], all_index[:, 0] = state_z, state_margin, state_index
        record = Level(threshold)
        for step in range(1, steps):
            candidate = propose(design, state_z, round_rng(seed, level, step))
            inside = np.ones(chains, dtype=bool) if in_support is None else np.asarray(in_support(candidate))
            run = np.array([run_index(design, level, step, c) for c in range(chains)], dtype=np.int64)
            candidate_margin = np.full(chains, np.inf)
            if inside.any():
                flown = np.asarray(evaluate(level, step, candidate[inside], run[inside]), dtype=float)
                candidate_margin[inside] = np.where(np.isnan(flown), -np.inf, flown)
            accept = inside & (candidate_margin <= threshold)
            state_z = np.where(accept[:, None], candidate, state_z)
            state_margin = np.where(accept, candidate_margin, state_margin)
            state_index = np.where(accept, run, state_index)
            all_z[:, step], all_margin[:, step], all_index[:, step] = state_z, state_margin, state_index
            record.flights += int(inside.sum())
            record.proposals += chains
            record.accepted += int(accept.sum())
            record.outside_support += int((~inside).sum())
        study.levels.append(record)
        z, margins, index = all_z.reshape(n, -1), all_margin.reshape(n), all_index.reshape(n)
        indicator_shape = (chains, steps)
    for record in study.levels:
        if record is study.levels[-1]:
            record.cov = _level_cov(record.probability, n, record.gamma)
        product *= record.probability
        if math.isfinite(record.cov):
            cov2 += record.cov**2
    study.probability = product
    study.cov = math.sqrt(cov2) if product > 0 else math.inf
    study.ci95 = interval(product, study.cov)
    study.z, study.margins, study.index = z, margins, index
    return study


def _gamma_of(indicator, shape, p):
    if shape is None:  # level 0: independent samples
        return 0.0
    return _chain_gamma(indicator.reshape(shape).astype(float), shape[0], shape[1], p)


def _level_cov(p, n, gamma):
    """Au & Beck eq. 25/28: c.o.v. of one level's conditional probability (inf when it is 0)."""
    if p <= 0.0:
        return math.inf
    return math.sqrt((1.0 - p) / (n * p) * (1.0 + gamma))


def interval(probability, cov):
    """The lognormal 95 % interval of an estimate with c.o.v. ``cov``: (lo, hi)."""
    if not probability > 0.0 or not math.isfinite(cov):
        return (0.0, math.nan if not probability > 0.0 else math.inf)
    width = Z95 * math.sqrt(math.log1p(cov * cov))
    return (probability * math.exp(-width), probability * math.exp(width))
