"""A run folder's config.yaml reproduces the run: every built-in scenario, written as the run folder writes it and
read back, is the same configuration (a commander script's commands included)."""

from __future__ import annotations

import dataclasses

import pytest
import yaml

from cufund.missions.commands import parse_command
from cufund.scenarios import ScenarioConfig, available_scenarios, load_scenario


@pytest.mark.parametrize("name", sorted(available_scenarios()))
def test_written_config_reads_back_the_same(name):
    cfg = load_scenario(name)
    text = yaml.safe_dump(cfg.to_dict(), sort_keys=False)
    again = ScenarioConfig.from_dict(yaml.safe_load(text), base_dir=cfg.base_dir)
    assert dataclasses.replace(again, base_dir=cfg.base_dir) == cfg


def test_a_command_writes_only_what_it_sets():
    for data in (
        {"command": "arm"},
        {"command": "takeoff", "altitude": 2.0},
        {"command": "disarm", "force": True},
        {"command": "goto", "p_W": [1.0, 2.0, 1.5], "yaw": 0.5, "id": 7},
        {"command": "mission_upload", "items": [{"p_W": [1.0, 0.0, 1.0], "yaw": None, "hold_s": 2.0}]},
        {"command": "mission_start", "seq": 0},
    ):
        cmd = parse_command(data)
        assert parse_command(cmd.to_data()) == cmd
        assert cmd.to_data() == data
