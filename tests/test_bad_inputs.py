"""Every case of the bad-input table (tests/bad_inputs.py): exit status 2, one ``error:`` line naming what is
wrong, no traceback, no phrase said twice, and nothing written."""
import pytest
from bad_inputs import CASES, doubled_phrase, run


@pytest.mark.parametrize("case", CASES, ids=[f"{c.issue}:{c.command}" for c in CASES])
def test_bad_input(case, tmp_path):
    res = run(case, tmp_path)
    lines = res.stderr.strip().splitlines()
    assert res.status == 2, (res.status, res.stderr, res.stdout)
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert "Traceback" not in res.stderr + res.stdout
    assert case.expect in lines[0], lines[0]
    assert doubled_phrase(lines[0]) is None, lines[0]
    assert res.changed == [], res.changed
