"""A damaged ``manifest.json`` is bad input for `refexmc report` and `refexmc compare`: one line
naming the file and what is wrong, exit 2, no traceback, nothing written (docs/interface.md)."""

import re

import pytest
from click.testing import CliRunner
from test_report import synthetic_runs, write_out

from refexmc.cli import main
from refexmc.config.errors import ConfigError
from refexmc.report import data

DAMAGED = [  # manifest.json's text, what the message says is wrong with it
    ("{\n", "not valid JSON"),  # a manifest cut short (a full disk, a hand edit)
    ("", "not valid JSON"),
    ("[]\n", "expected a JSON object, got a list"),
    ('"complete"\n', "expected a JSON object, got a string"),
    ("null\n", "expected a JSON object, got null"),
]


@pytest.fixture
def out(tmp_path):
    return write_out(tmp_path / "out", synthetic_runs(n=8, errored=(), failed=()), histories=False, parts=1)


def damage(out, text):
    (out / "manifest.json").write_text(text)


@pytest.mark.parametrize(("text", "message"), DAMAGED)
def test_load_names_the_manifest_and_what_is_wrong(out, text, message):
    damage(out, text)
    with pytest.raises(ConfigError, match=re.escape(message)) as raised:
        data.load(out)
    assert str(raised.value).startswith(str(out / "manifest.json"))


def test_invalid_json_names_its_line(out):
    damage(out, '{\n  "status": "complete",\n  "runs": 8,,\n}\n')
    with pytest.raises(ConfigError) as raised:
        data.load(out)
    assert raised.value.line == 3 and f"{out / 'manifest.json'}:3: not valid JSON" in str(raised.value)


@pytest.mark.parametrize(("text", "message"), DAMAGED)
def test_report_of_a_damaged_manifest_is_bad_input(out, text, message):
    damage(out, text)
    result = CliRunner().invoke(main, ["report", str(out)])
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit)  # not a traceback
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "manifest.json" in lines[0] and message in lines[0], result.output
    assert not (out / "report").exists()  # nothing written


@pytest.mark.parametrize(("text", "message"), DAMAGED)
@pytest.mark.parametrize("side", ["baseline", "current"])
def test_compare_with_a_damaged_manifest_is_bad_input(tmp_path, out, text, message, side):
    other = write_out(tmp_path / "other", synthetic_runs(n=8, errored=(), failed=()), histories=False, parts=1)
    damage(out, text)
    pair = [str(out), str(other)] if side == "baseline" else [str(other), str(out)]
    result = CliRunner().invoke(main, ["compare", *pair])
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit)  # not a traceback
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and str(out / "manifest.json") in lines[0] and message in lines[0], result.output
