"""``sampling: saltelli`` as the campaign file states it: the dispersed paths the design groups
and the checks that the design can estimate the campaign's Sobol' indices (docs/studies.md;
Saltelli et al. 2010, Comput. Phys. Commun. 181, 259-270). ``refexmc.campaign.saltelli`` builds
the design and hands each run its uniforms.

Each dispersed path is one input group (all its components together: a vector's three axes, a
valve constant's eight thrusters). With G groups and N base samples the design has N (G + 2)
rows. A campaign whose output is not a function of the design's uniforms cannot support it and
is refused: random or enumerated failures (their draws are not in the design), the ``inertia``
distribution (a non-physical draw is redrawn outside the design), and measurement noise (the
flight draws it from the run's own seed).
"""

from refexmc import distributions
from refexmc.config import dispersions
from refexmc.config.errors import ConfigError

NOISE_KEYS = (
    "attitude_noise_deg",
    "rate_noise_deg_s",
    "gps_position_noise_m",
    "gps_velocity_noise_m_s",
    "local_position_noise_m",
    "local_velocity_noise_m_s",
    "tank_pressure_noise_pa",
)


def layout(campaign, specs=None):
    """[(path, uniforms per draw)] of the dispersed paths that draw (constant ones do not)."""
    vehicle, mission = campaign["vehicle"], campaign["mission"]
    if specs is None:
        specs = dispersions.check(campaign["dispersions"], vehicle, mission, None, {})
    out = []
    for path, spec in specs.items():
        count = distributions.uniforms_per_draw(spec, dispersions.size(path, vehicle))
        if count:
            out.append((path, count))
    return out


def base_samples(dispersed_runs, groups):
    """N of a design with ``dispersed_runs`` rows over ``groups`` (None when not N (G + 2))."""
    n, remainder = divmod(dispersed_runs, len(groups) + 2)
    return n if remainder == 0 else None


def check(campaign, file=None, lines=None):
    """ConfigError (file, line, key path) unless a Saltelli design can estimate the campaign's Sobol' indices."""
    lines = lines or {}

    def fail(message, *path):
        raise ConfigError(message, file=file, line=lines.get(path) or lines.get(path[:1]), path=path)

    for key in ("failures", "wheel_failures"):
        mode = (campaign.get(key) or {}).get("mode", "none")
        if mode not in ("none", "fixed"):
            fail(f"sampling saltelli: failures of mode '{mode}' are drawn outside the design; use none or fixed", key)
    for path, spec in campaign["dispersions"].items():
        if spec.get("dist") == "inertia":
            fail(
                "sampling saltelli: the inertia distribution redraws non-physical tensors outside the design; "
                "disperse the inertia otherwise or leave it out",
                "dispersions",
                path,
            )
    navigation = campaign["mission"].get("navigation", {})
    for key in NOISE_KEYS:
        path = f"navigation.{key}"
        spec = campaign["dispersions"].get(path)
        noisy = (spec is not None and not (spec.get("dist") == "constant" and spec.get("value") == 0)) or (
            spec is None and navigation.get(key, 0.0) != 0.0
        )
        if noisy:
            fail(
                f"sampling saltelli: {path} is not 0; the flight draws its measurement noise from the run's seed, "
                "so a run's output would not be a function of the design (set it to 0, e.g. a constant dispersion)",
                "dispersions",
            )
    groups = layout(campaign)
    if not groups:
        fail("sampling saltelli needs dispersed parameters", "dispersions")
    dispersed = campaign["runs"] - (1 if campaign["nominal_first"] else 0)
    n_base = base_samples(dispersed, groups)
    if n_base is None or n_base < 2 or n_base & (n_base - 1):
        extra = 1 if campaign["nominal_first"] else 0
        options = ", ".join(str(n * (len(groups) + 2) + extra) for n in (64, 128, 256, 512, 1024))
        fail(
            f"sampling saltelli over {len(groups)} dispersed parameters needs N ({len(groups)} + 2) dispersed runs "
            f"with N a power of 2 (N >= 2), {'plus the nominal run, ' if extra else ''}e.g. runs: {options}; "
            f"got {campaign['runs']}",
            "runs",
        )


def runs_needed(groups, n_base, nominal_first=True):
    """Runs of a Saltelli design with ``n_base`` base samples over ``groups`` groups."""
    return n_base * (groups + 2) + (1 if nominal_first else 0)
