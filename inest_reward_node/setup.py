"""ament_python package, also pip-installable."""

from setuptools import find_packages, setup

PACKAGE = "inest_reward_node"

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
    description=(
        "INEST reward: TCC encoder, subtask goal embeddings and the learned reward "
        "with intrinsic exploration; ROS 2 reward node."
    ),
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "inest-reward-node = inest_reward_node.node:main",
            "inest-pretrain = inest_reward_node.learning.pretrain:main",
            "inest-reward-quality = inest_reward_node.learning.quality:main",
            "inest-exploit-suite = inest_reward_node.learning.exploit_check:main",
            "inest-model-card = inest_reward_node.learning.model_card:main",
            "inest-label-clips = inest_reward_node.learning.labels:main",
            "inest-import-demos = inest_reward_node.recordings.import_demos:main",
            "inest-label-demos = inest_reward_node.recordings.label_demos:main",
        ],
    },
)
