"""``vjm stiffness robot.yaml --q ...``: the CLI prints what the API computes."""
import json
import os

import numpy as np

import vjm
from vjm.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml")


def test_stiffness_and_sag_at_a_configuration_as_json(capsys):
    q = [0.1, -1.2, 1.5, -1.9, -1.57, 0.0]
    assert main(["stiffness", UR10, "--q", ",".join(map(str, q)), "--self-weight", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    m = vjm.load_model(UR10)
    tool = doc["tools"]["tool0"]
    assert np.allclose(tool["K"], m.stiffness(q).K, rtol=1e-12, atol=0)
    assert np.allclose(tool["self_weight_twist_mm_rad"], m.self_weight(q), rtol=1e-9, atol=1e-15)
    assert doc["joints"] == list(m.q_names)
