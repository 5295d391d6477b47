"""The beam-versus-FEA comparison is a typed value (:mod:`linkfea.beam.comparison`) that serialises to the
compare.json format: same keys, same order, same bytes after a round trip through the file."""
import dataclasses
import json

import numpy as np
import pytest

from linkfea.beam.compare import build_comparison, compare_link
from linkfea.beam.comparison import BeamFit, Comparison
from linkfea.cad import build_link
from linkfea.runtime.errors import LinkFeaError

#: compare.json's keys, in the file's order (the format users read; README "Beam or FEA?")
TOP_KEYS = ["link", "source", "params", "material", "frame", "beam_axis", "beam_length", "base_station",
            "tip_station", "units", "order", "fea", "beams", "definitions"]
BEAM_KEYS = ["n", "stations", "sections", "compliance_timoshenko", "compliance_euler_bernoulli", "timoshenko",
             "euler_bernoulli"]


@pytest.fixture(scope="module")
def bar():
    """The slender bar's comparison against a stand-in FEA matrix (SPD, with the eq. 14 couplings):
    the record's shape does not depend on where the matrix came from."""
    C = np.diag([1e-5, 4e-4, 1.6e-3, 2e-6, 1e-5, 1e-6])
    C[1, 5] = C[5, 1] = 1.5e-5
    C[2, 4] = C[4, 2] = -1e-4
    info = {"mode": "rigid", "mesh": {"n_tets": 10, "edge_length": 4.0}}
    link = build_link("bar")
    return link, C, info, build_comparison(link, C, (1, 2), fea_info=info)


def test_fields_are_the_file_keys_in_order(bar, tmp_path):
    _, C, info, cmp = bar
    cmp.save(tmp_path / "out")
    data = json.loads((tmp_path / "out" / "compare.json").read_text())
    assert list(data) == TOP_KEYS
    assert [f.metadata.get("key", f.name) for f in dataclasses.fields(Comparison)] == TOP_KEYS
    assert [f.name for f in dataclasses.fields(BeamFit)] == BEAM_KEYS
    assert [list(m) for m in data["beams"]] == [BEAM_KEYS, BEAM_KEYS]
    assert data["fea"] == {"compliance": C.tolist(), **info}
    assert [m["n"] for m in data["beams"]] == [1, 2]


def test_round_trip_through_the_file_is_byte_identical(bar, tmp_path):
    """compare.json -> Comparison.from_dict -> save writes the same bytes (json.loads of floats is exact)."""
    _, _, _, cmp = bar
    cmp.save(tmp_path / "a")
    text = (tmp_path / "a" / "compare.json").read_bytes()
    again = Comparison.from_dict(json.loads(text))
    assert isinstance(again.beams[0], BeamFit) and again.beams[1].n == 2
    again.save(tmp_path / "b")
    assert (tmp_path / "b" / "compare.json").read_bytes() == text
    assert (tmp_path / "b" / "compare.md").read_bytes() == (tmp_path / "a" / "compare.md").read_bytes()


def test_compare_link_is_the_typed_value_as_a_dict(bar):
    link, C, info, cmp = bar
    rec = compare_link(link, C, (1, 2), fea_info=info)
    assert json.dumps(rec, indent=1) == json.dumps(cmp.to_dict(), indent=1)


def test_typed_reading(bar):
    """The fields and the accessors read the same numbers as the dictionary."""
    _, C, _, cmp = bar
    rec = cmp.to_dict()
    assert cmp.link == rec["link"] == "bar"
    np.testing.assert_array_equal(cmp.fea, C)
    for m, d in zip(cmp.beams, rec["beams"]):
        np.testing.assert_array_equal(cmp.beam(m.n), np.array(d["compliance_timoshenko"]))
        np.testing.assert_array_equal(cmp.beam(m.n, "euler_bernoulli"), np.array(d["compliance_euler_bernoulli"]))
        assert m.timoshenko["summary"] == d["timoshenko"]["summary"]
    assert cmp.beam_length == pytest.approx(cmp.tip_station - cmp.base_station)
    assert len(cmp.errors) == 4
    with pytest.raises(LinkFeaError, match="no 3-beam model"):
        cmp.beam(3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cmp.link = "other"


def test_from_dict_names_missing_keys(bar):
    _, _, _, cmp = bar
    rec = cmp.to_dict()
    del rec["fea"], rec["units"]
    with pytest.raises(LinkFeaError, match="not a comparison record: no units, fea"):
        Comparison.from_dict(rec)
