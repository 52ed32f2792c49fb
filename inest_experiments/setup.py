"""ament_python package, also pip-installable."""

from setuptools import find_packages, setup

PACKAGE = "inest_experiments"

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
    description="INEST experiments: training-run grids, reports and summaries, re-evaluation, clip recording.",
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "inest-evaluate = inest_experiments.reevaluate:main",
            "inest-summarise = inest_experiments.summary:main",
            "inest-experiments = inest_experiments.experiments:main",
            "inest-record-clips = inest_experiments.record_clips:main",
            "inest-record-exploit-suite = inest_experiments.record_suite:main",
        ],
    },
)
