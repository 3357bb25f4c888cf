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
        (f"share/{package_name}/urdf", glob("urdf/*.urdf")),
        (f"share/{package_name}/rviz", glob("rviz/*.rviz")),
        (f"share/{package_name}/foxglove", glob("foxglove/*.json")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="boom_hydraulics maintainers",
    maintainer_email="maintainers@boom-hydraulics.org",
    description="Simulator of the hydraulic boom-lifting drive of a mobile crane-manipulator.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "boom_sim = boom_hydraulics.ros.boom_sim:main",
            "boom-sim = boom_hydraulics.cli.sim:main",
            "boom-demo = boom_hydraulics.ros.demo:main",
            "boom-analyze = boom_hydraulics.cli.analyze:main",
            "boom-study = boom_hydraulics.cli.study:main",
            "boom-replay = boom_hydraulics.ros.replay:main",
            "boom-resim = boom_hydraulics.cli.resim:main",
            "boom-bag-recover = boom_hydraulics.cli.recover:main",
            "boom-sweep = boom_hydraulics.cli.sweep:main",
            "boom-calibrate = boom_hydraulics.cli.calibrate:main",
        ],
    },
)
