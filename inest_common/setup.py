"""ament_python package, also pip-installable."""

from setuptools import find_packages, setup

PACKAGE = "inest_common"

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
    description="Shared INEST plumbing: atomic versioned files, progress lines, ROS 2 node helpers",
    license="Apache-2.0",
    python_requires=">=3.11",
)
