"""Data never executes: model files, machine descriptions (and their expressions) and file names
that try to run something are refused with one line, and nothing runs.

Each attempt would create a marker file in the test's folder; the marker's absence is the check
that nothing ran (independent of the message).  CAD scripts are code by design (README,
"Security") and are not tested here.
"""
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from linkfea.cli import app as linkfea_app
from vjm.cli import app as vjm_app
from vjm.errors import VjmError
from vjm.modelio.read import load_model
from vjm.resources import data_dir

MARK = "MARKER"
PUU = data_dir() / "orthoglide" / "puu.yaml"
DELTA = data_dir() / "machines" / "linear_delta.yaml"

TAGS = [
    f'!!python/object/apply:os.system ["touch {MARK}"]',
    f'!!python/object/new:subprocess.Popen [["touch", "{MARK}"]]',
    f'!!python/object/apply:builtins.exec ["open(\'{MARK}\', \'w\')"]',
    "!!python/name:os.system",
    "!!python/module:os",
    "!custom 3",
]


@pytest.fixture
def here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _one_error_line(result) -> str:
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    return lines[0]


def _vjm_stiffness(path) -> str:
    return _one_error_line(CliRunner().invoke(vjm_app, ["stiffness", str(path), "--at", "0,0,0"]))


@pytest.mark.parametrize("tag", TAGS)
@pytest.mark.parametrize("source,key", [(PUU, "  L: "), (DELTA, "  R: ")])
def test_yaml_tags_are_refused_naming_the_tag(here, tag, source, key):
    lines = source.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(key))
    lines[i] = key + tag
    bad = here / "model.yaml"
    bad.write_text("\n".join(lines) + "\n")
    msg = _vjm_stiffness(bad)
    shown = tag.split()[0] if tag.startswith("!!") else "!custom"
    assert f"line {i + 1}: the YAML tag {shown.split(' ')[0]}" in msg and "not allowed" in msg, msg
    with pytest.raises(VjmError, match="not allowed"):
        load_model(bad)
    assert not (here / MARK).exists()


EXPRESSIONS = [
    (f"__import__('os').system('touch {MARK}')", "calling system()"),
    (f"open('{MARK}', 'w')", "calling open()"),
    ("(lambda: 1)()", "a call"),
    ("R.__class__", "attribute access .__class__"),
    ("sin.__self__", "attribute access .__self__"),
    ("[R][0]", "indexing"),
    (f"'{MARK}'", "a constant that is no number"),
    ("-" * 990 + "R", "nested too deeply"),
    ("1+" * 600 + "R", "too long"),
]


@pytest.mark.parametrize("expr,what", EXPRESSIONS)
def test_description_expressions_never_run_code(here, expr, what):
    text = DELTA.read_text()
    assert "[Tx(R), " in text
    bad = here / "delta.yaml"
    bad.write_text(text.replace("[Tx(R), ", f'["Tx({expr})", ', 1))
    msg = _vjm_stiffness(bad)
    assert what in msg, msg
    assert not (here / MARK).exists()


NAMES = [f"$(touch {MARK})", f"`touch {MARK}`", f"bar; touch {MARK}", f"bar && touch {MARK}", f"|touch {MARK}",
         f"__import__('os').system('touch {MARK}')", f"$(touch {MARK}).step", f"x;touch {MARK}.stl"]


@pytest.mark.parametrize("name", NAMES)
def test_file_names_are_names(here, name):
    msg = _one_error_line(CliRunner().invoke(linkfea_app, ["compute", name, "--base", "plane:x=0", "--tip",
                                                           "plane:x=1", "--out", "o/r.json"]))
    assert "not found" in msg or "no link script" in msg or "no such file" in msg.lower(), msg
    msg = _vjm_stiffness(name)
    assert "not found" in msg, msg
    assert not (here / MARK).exists() and not (here / "o").exists()


def test_link_paths_inside_a_model_file_are_names(here):
    text = PUU.read_text()
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("foot:"))
    j = i + 1
    while j < len(lines) and (lines[j].startswith(" ") or not lines[j].strip()):
        j += 1
    lines[i:j] = [f'foot: {{linkfea: "$(touch {MARK}).json"}}']
    bad = here / "model.yaml"
    bad.write_text("\n".join(lines) + "\n")
    msg = _vjm_stiffness(bad)
    assert MARK in msg, msg
    assert not (here / MARK).exists()
    assert sorted(os.listdir(here)) == ["model.yaml"]


def test_model_file_with_python_inside_is_not_run(here):
    """A model file that is a Python script is read as YAML (and refused), never imported."""
    py = Path(here / "model.yaml")
    py.write_text(f"import os\nos.system('touch {MARK}')\n")
    _vjm_stiffness(py)
    assert not (here / MARK).exists()
