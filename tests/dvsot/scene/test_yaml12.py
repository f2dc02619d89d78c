"""YAML 1.2 (ruamel.yaml) in scene files and --option values: none of YAML 1.1's traps; duplicate keys by line."""

import pytest
from synthetic import MINIMAL_SCENE

from dvsot.core.errors import UserError
from dvsot.scene import load_scene, yaml_value


def write(tmp_path, text):
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


def test_yaml_1_1_traps_are_gone():
    # YAML 1.1 (PyYAML) reads 010 as 8, 1:30 as 90, on/no/y as booleans and 1e-3 as a string
    assert yaml_value("010") == 10 and yaml_value("0o10") == 8
    assert yaml_value("1:30") == "1:30"
    assert [yaml_value(v) for v in ("on", "no", "y", "off")] == ["on", "no", "y", "off"]
    assert yaml_value("1e-3") == 0.001 and yaml_value("False") is False and yaml_value("true") is True


def test_seed_010_is_ten_and_1_30_is_no_seed(tmp_path):
    assert load_scene(write(tmp_path, MINIMAL_SCENE + "seed: 010\n")).seed == 10
    with pytest.raises(UserError, match=r"s.yaml:9: field 'seed': Input should be a valid integer"):
        load_scene(write(tmp_path, MINIMAL_SCENE + "seed: 1:30\n"))


def test_a_key_twice_in_a_nested_mapping_names_both_lines(tmp_path):
    text = MINIMAL_SCENE + "events:\n  cp: 0.2\n  cn: 0.2\n  cp: 0.3\n"
    with pytest.raises(UserError, match=r"s.yaml:12: field 'cp' is given twice \(first on line 10\)"):
        load_scene(write(tmp_path, text))
