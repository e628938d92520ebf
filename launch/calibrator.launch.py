"""Start the rwhec_ros calibrator with a parameter file.

    ros2 launch rwhec_ros calibrator.launch.py config:=/path/to/my_setup.yaml [namespace:=rig1]
    ros2 service call /calibrate std_srvs/srv/Trigger          (or /<namespace>/calibrate)

The parameter file is the one configuration format of the package (see config/*.yaml and
rwhec_ros/config/). Its sections apply by ROS's rule for the node /<namespace>/calibrator: the
shipped files use ``/**`` (any node, any namespace), so ``namespace:=rig1`` works with them; a
section named ``calibrator`` would apply only without a namespace (``/**/calibrator`` works in any).
Outputs go to $ROS_HOME/rwhec_ros (~/.ros/rwhec_ros) unless output.directory says otherwise.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    default_config = PathJoinSubstitution(
        [FindPackageShare("rwhec_ros"), "config", "mobile_rig_mocap.yaml"]
    )
    return LaunchDescription([
        DeclareLaunchArgument(
            "config", default_value=default_config,
            description="ROS 2 parameter file of the calibrator (see config/*.yaml)",
        ),
        DeclareLaunchArgument("namespace", default_value="", description="node namespace"),
        DeclareLaunchArgument(
            "use_sim_time", default_value="false", description="use /clock (bag playback)"
        ),
        Node(
            package="rwhec_ros",
            executable="calibrator",
            name="calibrator",
            namespace=LaunchConfiguration("namespace"),
            parameters=[
                LaunchConfiguration("config"),
                {"use_sim_time": LaunchConfiguration("use_sim_time")},
            ],
            output="screen",
            emulate_tty=True,
        ),
    ])
