"""ament_python package, also pip-installable (console scripts land in bin/ under pip)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "inest_bringup"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
        (f"share/{PACKAGE}/config", glob("config/*")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="INEST developers",
    maintainer_email="dev@inest.invalid",
    description="Starting and watching the INEST node graph",
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "inest-launch = inest_bringup.launcher:main",
            "inest-monitor = inest_bringup.monitor:main",
            "inest-record = inest_bringup.recorder:main",
        ],
    },
)
