"""Build script of the boom_hydraulics ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "boom_hydraulics"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={"boom_hydraulics.fmu": ["native/*.c"]},  # the FMU's FMI wrapper, compiled at export
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
            # (each behind a Ctrl-C guard while its modules load: boom_hydraulics/entry_points.py)
            "boom_sim = boom_hydraulics.entry_points:boom_sim",
            "boom-sim = boom_hydraulics.entry_points:sim",
            "boom-demo = boom_hydraulics.entry_points:demo",
            "boom-analyze = boom_hydraulics.entry_points:analyze",
            "boom-study = boom_hydraulics.entry_points:study",
            "boom-replay = boom_hydraulics.entry_points:replay",
            "boom-resim = boom_hydraulics.entry_points:resim",
            "boom-bag-recover = boom_hydraulics.entry_points:bag_recover",
            "boom-sweep = boom_hydraulics.entry_points:sweep",
            "boom-calibrate = boom_hydraulics.entry_points:calibrate",
        ],
    },
)
