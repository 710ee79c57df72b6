"""The user documentation stays in step with the code: parameter table, paths, campaign files, examples."""

import importlib.util
import re
from pathlib import Path

import pytest
import yaml

from refexmc.config import dispersions
from refexmc.config.errors import ConfigError
from refexmc.config.load import failure_sets, load_campaign, load_mission, load_vehicle

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CAMPAIGNS_DOC = DOCS / "campaigns.md"
SWEEP_DOC = DOCS / "failure-sweep.md"
CAMPAIGN_FILES = sorted((ROOT / "campaigns").glob("*.yaml"))


def _module(name):
    spec = importlib.util.spec_from_file_location(name, DOCS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def generator():
    return _module("gen_parameter_table")


@pytest.fixture(scope="module")
def doc_text():
    return CAMPAIGNS_DOC.read_text()


def _between(text, begin, end):
    assert text.count(begin) == 1 and text.count(end) == 1, f"expected one {begin} and one {end} marker"
    return text.split(begin, 1)[1].split(end, 1)[0]


def test_parameter_table_is_generated_from_the_registry(generator, doc_text):
    in_doc = _between(doc_text, generator.BEGIN, generator.END).strip("\n")
    assert in_doc == generator.table().strip("\n"), (
        "the parameter table in docs/campaigns.md differs from dispersions.PARAMETERS; "
        "refresh it with: .venv/bin/python docs/gen_parameter_table.py --write"
    )


def test_every_parameter_path_is_documented(generator, doc_text):
    table = _between(doc_text, generator.BEGIN, generator.END)
    missing = [path for path in dispersions.PARAMETERS if f"| `{path}` |" not in table]
    assert not missing, f"paths missing from the table in docs/campaigns.md: {missing}"


@pytest.mark.parametrize("path", CAMPAIGN_FILES, ids=lambda p: p.name)
def test_campaign_files_validate_and_use_documented_paths(path, generator, doc_text):
    campaign = load_campaign(path)  # ConfigError (the test fails with its message) on bad input
    table = _between(doc_text, generator.BEGIN, generator.END)
    undocumented = [p for p in campaign["dispersions"] if f"| `{p}` |" not in table]
    assert not undocumented, f"{path.name} disperses paths not in docs/campaigns.md: {undocumented}"


def test_every_campaign_key_is_in_the_key_table(doc_text):
    """docs/campaigns.md section 1 has a row for each top-level key the campaign schema accepts."""
    from refexmc.config import schema

    table = doc_text.split("## 1. Campaign keys", 1)[1].split("\n\n", 2)[1]
    rows = re.findall(r"^\| `([a-z_]+)", table, flags=re.M)
    assert sorted(set(rows)) == sorted(schema.CAMPAIGN["properties"])


def test_the_shipped_campaigns_are_listed(doc_text):
    unlisted = [p.name for p in CAMPAIGN_FILES if f"`campaigns/{p.name}`" not in doc_text]
    assert not unlisted, f"campaign files not listed in docs/campaigns.md: {unlisted}"


def _yaml_examples(text):
    return [yaml.safe_load(block) for block in re.findall(r"```yaml\n(.*?)```", text, flags=re.S)]


def test_yaml_examples_in_the_doc_validate(doc_text, tmp_path):
    """Each ```yaml block is a campaign file, or a fragment added to campaigns/nominal.yaml."""
    examples = _yaml_examples(doc_text)
    assert len(examples) >= 5
    base = yaml.safe_load((ROOT / "campaigns/nominal.yaml").read_text())
    for k, example in enumerate(examples):
        data = dict(example) if "vehicle" in example else {**base, **example}
        if data.get("failures", {}).get("mode") == "enumerate":
            data.pop("runs", None)
        for part in ("vehicle", "mission"):
            data[part] = str((ROOT / "campaigns" / data[part]).resolve())
        file = tmp_path / f"example-{k}.yaml"
        file.write_text(yaml.safe_dump(data))
        try:
            load_campaign(file)
        except ConfigError as exc:  # pragma: no cover - the message is the diagnosis
            pytest.fail(f"example {k} of docs/campaigns.md does not validate: {exc}")


def test_distribution_column_matches_the_checks(generator):
    """The 'distributions' column: inertia only on the inertia tensor, uniform_so3 only on the attitude."""
    vehicle = load_vehicle(ROOT / "configs/vehicles/refex.yaml")
    mission = load_mission(ROOT / "configs/missions/refex-exo.yaml")
    specs = {"uniform_so3": {"dist": "uniform_so3"}, "inertia": {"dist": "inertia", "moments_sigma_fraction": 0.01}}
    for path, param in dispersions.PARAMETERS.items():
        documented = generator._DISTRIBUTIONS.get(param.shape, generator._DEFAULT_DISTRIBUTIONS)
        for dist, spec in specs.items():
            try:
                dispersions.check({path: spec}, vehicle, mission, None, {})
                accepted = True
            except ConfigError:
                accepted = False
            says_accepted = f"`{dist}` only" in documented or (
                f"`{dist}`" not in documented and "`inertia` only" not in documented
            )
            assert accepted == says_accepted, (path, dist, documented)


def test_failure_sweep_doc_lists_every_set_in_run_order():
    """docs/failure-sweep.md has one row per run of campaigns/failure-sweep.yaml (not flown here)."""
    sweep = _module("gen_failure_sweep")
    campaign = load_campaign(ROOT / "campaigns/failure-sweep.yaml")
    rows = re.findall(
        r"^\| (\d+) \| (none|\[[\d, ]+\]) \|", _between(SWEEP_DOC.read_text(), sweep.BEGIN, sweep.END), re.M
    )
    expected = [()] + failure_sets(campaign["failures"]["sizes"], len(campaign["vehicle"]["rcs"]["thrusters"]))
    assert [int(run) for run, _ in rows] == list(range(campaign["runs"]))
    assert [() if s == "none" else tuple(int(t) for t in s.strip("[]").split(", ")) for _, s in rows] == expected


def test_every_exit_code_is_in_the_interface_table():
    """docs/interface.md's exit-code table lists what the commands return, interrupted runs included."""
    import signal

    from refexmc.campaign.run import CampaignInterrupted

    table = (DOCS / "interface.md").read_text().split("Exit codes, every command:", 1)[1].split("\n\n")[1]
    codes = [int(code) for code in re.findall(r"^\| (\d+) \|", table, flags=re.M)]
    interrupted = [CampaignInterrupted(signum).exit_code for signum in (signal.SIGINT, signal.SIGTERM)]
    assert codes == [0, 1, 2, *interrupted] == [0, 1, 2, 130, 143]


def test_missions_doc_names_every_kind_target_and_predicate():
    """docs/missions.md documents the whole mode vocabulary the schema accepts."""
    from refexmc.config import schema

    text = (ROOT / "docs" / "missions.md").read_text()
    names = [*schema.MODE_KINDS, *schema.TARGET_TYPES, *schema.EXIT_PREDICATES]
    missing = [name for name in names if f"`{name}" not in text]
    assert not missing, f"docs/missions.md does not describe: {missing}"
