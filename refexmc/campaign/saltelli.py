"""``sampling: saltelli``: the Saltelli design of SALib over the dispersed parameters, for Sobol'
indices (docs/studies.md; Saltelli et al. 2010, Comput. Phys. Commun. 181, 259-270).

Each dispersed path is one input group (all its components together: a vector's three axes, a
valve constant's eight thrusters). With G groups and N base samples the design has N (G + 2)
rows in SALib's order (per base sample: A, the G rows of A with one group from B, then B), and
dispersed run i (run 0 is the nominal run when ``nominal_first``) takes row i's uniforms,
through the same inverse-CDF transforms as every other sampling. The design comes from SALib's
scrambled Sobol' sequence seeded by the campaign seed, so it is the same on every machine.

What a design cannot support is refused when the campaign is validated (``refexmc.config.saltelli``).
"""

import functools

import numpy as np

from refexmc.config.saltelli import base_samples, layout


def problem(groups):
    """SALib's problem: one variable per uniform on [0, 1], grouped by path."""
    names = [f"{path}[{k}]" for path, count in groups for k in range(count)]
    return {
        "num_vars": len(names),
        "names": names,
        "bounds": [[0.0, 1.0]] * len(names),
        "groups": [path for path, count in groups for _ in range(count)],
    }


@functools.lru_cache(maxsize=8)
def _design(seed, groups, n_base):
    from SALib.sample import sobol

    seed32 = int(np.random.SeedSequence([int(seed), 0x5A17E111]).generate_state(1)[0])
    design = sobol.sample(problem(list(groups)), n_base, calc_second_order=False, scramble=True, seed=seed32)
    design.setflags(write=False)
    return design


def uniforms(sampler, path, rows):
    """The design's uniforms of ``path`` at design rows ``rows`` (len(rows) x its uniforms)."""
    groups = tuple(layout(sampler.campaign, sampler.specs))
    n_base = base_samples(sampler.n_dispersed, groups)
    start = 0
    for name, count in groups:
        if name == path:
            return _design(sampler.seed, groups, n_base)[np.asarray(rows, dtype=np.int64), start : start + count]
        start += count
    raise KeyError(path)  # pragma: no cover - constant paths draw no uniforms
