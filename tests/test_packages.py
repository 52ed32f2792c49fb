"""Repository layout: proper ament_python packages, also pip-installed; pure logic without rclpy."""

from __future__ import annotations

import configparser
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("inest_sim_node", "inest_reward_node", "inest_agent_node")


@pytest.mark.parametrize("package", PACKAGES)
def test_ament_python_package(package):
    folder = ROOT / package
    manifest = ET.parse(folder / "package.xml").getroot()
    assert manifest.get("format") == "3"
    assert manifest.findtext("name") == package
    assert manifest.find("export/build_type").text == "ament_python"
    assert (folder / "resource" / package).is_file()
    setup_cfg = configparser.ConfigParser()
    setup_cfg.read(folder / "setup.cfg")
    assert setup_cfg["install"]["install_scripts"] == f"$base/lib/{package}"
    assert setup_cfg["develop"]["script_dir"] == f"$base/lib/{package}"
    link = ROOT / "ros2_ws" / "src" / package
    assert link.resolve() == folder.resolve()


def test_simulator_logic_does_not_import_rclpy():
    code = (
        "import sys, inest_sim_node.collect, inest_sim_node.video, inest_sim_node.expert;"
        "assert 'rclpy' not in sys.modules, 'rclpy was imported'"
    )
    # run outside the repository root, where the ament folder would shadow the installed package
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT / "tests")


def test_rclpy_is_available_from_the_wheels():
    subprocess.run(
        [sys.executable, "-c", "import rclpy, sensor_msgs.msg, std_msgs.msg"], check=True, cwd=ROOT / "tests"
    )
