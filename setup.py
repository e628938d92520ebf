"""ament_python build script (colcon needs setup.py; pyproject.toml holds tool settings only)."""

from glob import glob

from setuptools import find_packages, setup

package_name = "rwhec_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "benchmarks"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),
    ],
    python_requires=">=3.10",
    install_requires=[
        "setuptools",
        "numpy>=1.24",
        "scipy>=1.11",
        "cvxpy>=1.5",
        "clarabel>=0.9",
        # sparse LDL^T (AMD ordering) of the large-rig path; also a dependency of cvxpy/OSQP
        "qdldl>=0.1.9",
        # 4.x only: the 5.0 Python wheel lacks calibrateHandEye / calibrateRobotWorldHandEye.
        "opencv-contrib-python-headless>=4.10,<5",
        "PyYAML>=6",
        "threadpoolctl>=3",
        "matplotlib>=3.6",  # Ubuntu 24.04's python3-matplotlib is 3.6.3 (tested by .ci/run)
        "rosbags>=0.10",
    ],
    extras_require={"test": ["pytest>=7"]},
    zip_safe=True,
    maintainer="rwhec_ros developers",
    maintainer_email="rwhec-ros@example.com",
    description=(
        "Certifiably globally optimal multi-sensor robot-world/hand-eye calibration for ROS 2"
    ),
    license="BSD-3-Clause",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "calibrator = rwhec_ros.ros.entry:calibrator",
            "rwhec_demo_sim = rwhec_ros.ros.entry:demo_sim",
            "rwhec-calibrate = rwhec_ros.cli:main",
        ],
    },
)
