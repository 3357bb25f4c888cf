"""Build script of the boom_hydraulics ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "boom_hydraulics"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
        (f"share/{package_name}/config", glob("config/*.yaml")),
        (f"share/{package_name}/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="boom_hydraulics maintainers",
    maintainer_email="maintainers@boom-hydraulics.org",
    description="Simulator of the hydraulic boom-lifting drive of a mobile crane-manipulator.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "boom_sim = boom_hydraulics.node:main",
            "boom-sim = boom_hydraulics.cli:main",
            "boom-demo = boom_hydraulics.demo:main",
            "boom-analyze = boom_hydraulics.analyze:main",
            "boom-study = boom_hydraulics.study:main",
            "boom-replay = boom_hydraulics.replay:main",
            "boom-resim = boom_hydraulics.resim:main",
            "boom-bag-recover = boom_hydraulics.recovery:main",
            "boom-sweep = boom_hydraulics.sweep_cli:main",
        ],
    },
)
