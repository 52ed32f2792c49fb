"""ament_python package, also pip-installable (console scripts land in bin/ under pip)."""

from setuptools import find_packages, setup

PACKAGE = "inest_sim_node"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="INEST developers",
    maintainer_email="dev@inest.invalid",
    description="Sweep-to-top-in-order simulator, scripted expert and demonstration datasets",
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "inest-sim-node = inest_sim_node.node:main",
            "inest-collect-demos = inest_sim_node.collect:main",
            "inest-export-video = inest_sim_node.video:main",
            "inest-teleop-standin = inest_sim_node.teleop:main",
        ],
    },
)
