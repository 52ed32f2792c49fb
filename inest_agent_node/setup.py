"""ament_python package, also pip-installable."""

from setuptools import find_packages, setup

PACKAGE = "inest_agent_node"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", ["config/train.yaml", "config/grid.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="INEST developers",
    maintainer_email="dev@inest.invalid",
    description="INEST agent: SAC policy learning on the learned reward, in process or over ROS 2 topics.",
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "inest-agent-node = inest_agent_node.node:main",
            "inest-train = inest_agent_node.train:main",
        ],
    },
)
