"""Every effect the absolute-pose diagnosis can name has a test against an independent truth (pinocchio in
tests/truth_serial.py for robots, tests/truth_parallel.py for the hexapod), as ``test_diagnose_truth.py``
asks of the deflection library: a new stage or effect without such a test fails here.  (Tests that run
the package's own simulator check files, arguments and progress, never an effect's shape.)"""
import ast
import os

from vjm.effects.absolute import names

HERE = os.path.dirname(os.path.abspath(__file__))

#: effect -> (test file, test function that hides it in truth data and checks it is named)
ROBOT = {
    "geometry": ("test_robot_calibration.py", "test_hidden_effects_are_named_and_recovered"),
    "compliance": ("test_robot_calibration.py", "test_hidden_effects_are_named_and_recovered"),
    "coupling": ("test_robot_truth_cases.py", "test_a_joint_coupled_to_another_is_named"),
    "lateral": ("test_robot_flex_truth.py", "test_a_hidden_flex_effect_is_named_and_recovered"),
    "bending": ("test_robot_flex_truth.py", "test_a_hidden_flex_effect_is_named_and_recovered"),
    "varying": ("test_robot_flex_truth.py", "test_a_hidden_flex_effect_is_named_and_recovered"),
    "thermal": ("test_robot_flex_truth.py", "test_a_hidden_flex_effect_is_named_and_recovered"),
    "tilt": ("test_robot_truth_cases.py", "test_a_base_tilt_is_named_through_the_compliances"),
    "backlash": ("test_robot_truth_cases.py", "test_backlash_flipping_with_the_gravity_torque_is_named"),
    "payload": ("test_robot_calibration.py", "test_a_payload_at_the_marker_is_weighed_through_the_compliances"),
    "guide_tilt": ("test_guide_tilt.py", "test_a_tilting_guide_is_named_and_its_compliance_recovered"),
    "column_tilt": ("test_column_truth.py", "test_the_whole_library_names_the_column_alone_and_recovers_it"),
    "link_scale": ("test_link_scale.py", "test_a_link_more_compliant_than_its_cad_is_scaled"),
}
PARALLEL = {
    "offset": ("test_parallel_poses_truth.py", "test_hidden_strut_offsets_are_named_and_recovered"),
    "attachment": ("test_parallel_poses_truth.py", "test_a_moved_base_joint_is_named_as_an_attachment"),
}


def _module(name):
    with open(os.path.join(HERE, name), encoding="utf-8") as f:
        return ast.parse(f.read())


def _uses_truth(tree) -> bool:
    names = {a.name for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom)) for a in n.names}
    calls = {c.args[0].value for c in ast.walk(tree) if isinstance(c, ast.Call) and c.args
             and isinstance(c.args[0], ast.Constant) and getattr(c.func, "attr", "") == "importorskip"}
    return bool({"truth_serial", "truth_parallel"} & (names | calls))


def test_every_effect_has_a_truth_test():
    assert set(ROBOT) == set(names("serial")), set(names("serial")) ^ set(ROBOT)
    assert set(PARALLEL) == set(names("parallel")), set(names("parallel")) ^ set(PARALLEL)
    for effect, (file, test) in {**ROBOT, **PARALLEL}.items():
        tree = _module(file)
        assert _uses_truth(tree), f"{file}: no independent truth module"
        assert test in {f.name for f in tree.body if isinstance(f, ast.FunctionDef)}, (effect, file, test)


def test_each_flex_effect_is_one_of_the_flex_truth_cases():
    tree = _module("test_robot_flex_truth.py")
    cases = next(n.value for n in tree.body if isinstance(n, ast.Assign) and n.targets[0].id == "CASES")
    keys = {k.value for k in cases.keys}
    assert {e for e, (f, _) in ROBOT.items() if f == "test_robot_flex_truth.py"} <= keys, keys
