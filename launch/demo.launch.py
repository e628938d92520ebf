"""Demo: a simulated mobile rig (3 cameras, 6 AprilTags, motion-capture poses) + the calibrator.

    ros2 launch rwhec_ros demo.launch.py
    ros2 service call /calibrate std_srvs/srv/Trigger          # after ~20 s of motion
    ros2 topic echo --once --qos-durability transient_local --qos-reliability reliable \
        /calibrator/suboptimality_bound

The simulator (rwhec_demo_sim, model in rwhec_ros/simulation/rig.py) publishes /demo/rig/pose,
/demo/<cam>/image_raw and /demo/<cam>/camera_info, plus the TRUE extrinsics on /tf_static as
*_true frames; the calibrator (config/demo.yaml) publishes its estimates as *_calibrated frames.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("rwhec_ros"), "config", "demo.yaml"])
    return LaunchDescription([
        DeclareLaunchArgument("rate_hz", default_value="5.0", description="image rate [Hz]"),
        DeclareLaunchArgument("seed", default_value="0", description="simulation seed"),
        Node(
            package="rwhec_ros",
            executable="rwhec_demo_sim",
            name="rwhec_demo_sim",
            parameters=[{
                "rate_hz": LaunchConfiguration("rate_hz"),
                "seed": LaunchConfiguration("seed"),
            }],
            output="screen",
            emulate_tty=True,
        ),
        Node(
            package="rwhec_ros",
            executable="calibrator",
            name="calibrator",
            parameters=[config],
            output="screen",
            emulate_tty=True,
        ),
    ])
