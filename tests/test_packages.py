"""Repository layout: proper ament_python packages, also pip-installed; pure logic without rclpy."""

from __future__ import annotations

import configparser
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("inest_common", "inest_sim_node", "inest_reward_node", "inest_agent_node", "inest_experiments")


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


# top-level import -> the rosdep key package.xml declares it as (`-pip`: installed from PyPI, pinned
# in requirements.txt; docker/Dockerfile skips those keys in `rosdep install`)
ROSDEP_KEYS = {
    "numpy": "python3-numpy",
    "cv2": "python3-opencv",
    "PIL": "python3-pil",
    "tqdm": "python3-tqdm",
    "scipy": "python3-scipy",
    "matplotlib": "python3-matplotlib",
    "yaml": "python3-yaml",
    "pymunk": "python3-pymunk-pip",
    "gymnasium": "python3-gymnasium-pip",
    "torch": "python3-torch-pip",
    "safetensors": "python3-safetensors-pip",
    "tensorboard": "python3-tensorboard-pip",
    "stable_baselines3": "python3-stable-baselines3-pip",
    "sb3_contrib": "python3-sb3-contrib-pip",
    "sbx": "python3-sbx-rl-pip",
    "jax": "python3-jax-pip",
    "flax": "python3-flax-pip",
    "msgpack": "python3-msgpack-pip",
    "mcap": "python3-mcap-pip",
    "mcap_ros2": "python3-mcap-ros2-support-pip",
    "ray": "python3-ray-pip",
    "rosbags": "python3-rosbags-pip",
    "pyarrow": "python3-pyarrow-pip",
    "av": "python3-av-pip",
}
# imports no import statement shows: by name (learners.LEARNERS) or through another library
INDIRECT_IMPORTS = {
    "inest_reward_node": {"tensorboard"},  # torch.utils.tensorboard.SummaryWriter
    "inest_agent_node": {"tensorboard", "sb3_contrib"},  # SB3's tensorboard_log; learners.LEARNERS["crossq"]
}


def imported_modules(package: str) -> set[str]:
    """Top-level names of every module the package's sources import (lazy imports included)."""
    import ast

    names: set[str] = set()
    for source in (ROOT / package / package).rglob("*.py"):  # subpackages too (runtime/, learning/)
        for node in ast.walk(ast.parse(source.read_text())):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return (names | INDIRECT_IMPORTS.get(package, set())) - set(sys.stdlib_module_names) - {package}


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_declares_every_import(package):
    manifest = ET.parse(ROOT / package / "package.xml").getroot()
    declared = {element.text for element in manifest if element.tag in ("depend", "exec_depend")}
    missing = []
    for module in sorted(imported_modules(package)):
        key = ROSDEP_KEYS.get(module, module)  # ROS packages (rclpy, *_msgs, inest_*) are their own keys
        if key not in declared:
            missing.append(f"{module} (as {key})")
    assert not missing, f"{package}/package.xml lacks: {', '.join(missing)}"


def test_docker_skips_the_keys_pip_installs():
    keys = set()
    for package in PACKAGES:
        manifest = ET.parse(ROOT / package / "package.xml").getroot()
        keys |= {element.text for element in manifest if element.text and element.text.endswith("-pip")}
    dockerfile = (ROOT / "docker" / "Dockerfile").read_text()
    assert all(key in dockerfile for key in keys), sorted(key for key in keys if key not in dockerfile)


# the only modules that may import rclpy (teleop: the stand-in operator, a node over the expert)
ROS_ADAPTERS = {"node", "graph_env", "rosutil", "teleop"}


@pytest.mark.parametrize("package", PACKAGES)
def test_only_the_ros_adapters_import_rclpy(package):
    modules = sorted(
        f"{package}.{path.stem}"
        for path in (ROOT / package / package).glob("*.py")
        if path.stem not in ROS_ADAPTERS | {"__init__"}
    )
    code = (
        f"import sys, importlib; [importlib.import_module(m) for m in {modules!r}]; assert 'rclpy' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
