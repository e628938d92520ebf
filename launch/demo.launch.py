"""Demo: a simulated mobile rig (3 cameras, 6 AprilTags, motion-capture poses) + the calibrator.

    ros2 launch rwhec_ros demo.launch.py [boards:=true|grids]
    ros2 service call /calibrate std_srvs/srv/Trigger          # after ~15-20 s of motion
    ros2 topic echo --once --qos-durability transient_local --qos-reliability reliable \
        /calibrator/suboptimality_bound

The simulator (rwhec_demo_sim, model in rwhec_ros/simulation/rig.py) publishes /demo/rig/pose,
/demo/<cam>/image_raw and /demo/<cam>/camera_info, plus the TRUE extrinsics on /tf_static as
*_true frames; the calibrator (config/demo.yaml) publishes its estimates as *_calibrated frames.
With boards:=true the simulator renders an AprilGrid and a ChArUco board in place of tags 0 and 1
(its parameter boards: [aprilgrid, charuco]) and the calibrator reads config/demo_boards.yaml,
which describes them (frames board_0, board_1). With boards:=grids it renders a chessboard, a circle
grid with an origin circle and an asymmetric circle grid in place of tags 0, 1 and 2 (boards:
[chessboard, circles, asymmetric_circles]) and the calibrator reads config/demo_grids.yaml.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import EqualsSubstitution, LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

#: The boards of the simulator with boards:=true, described by config/demo_boards.yaml.
DEMO_BOARDS = ["aprilgrid", "charuco"]
#: The boards of the simulator with boards:=grids, described by config/demo_grids.yaml.
DEMO_GRIDS = ["chessboard", "circles", "asymmetric_circles"]


def generate_launch_description():
    share = FindPackageShare("rwhec_ros")
    sim = {"rate_hz": LaunchConfiguration("rate_hz"), "seed": LaunchConfiguration("seed")}
    actions = [
        DeclareLaunchArgument("rate_hz", default_value="5.0", description="image rate [Hz]"),
        DeclareLaunchArgument("seed", default_value="0", description="simulation seed"),
        DeclareLaunchArgument("boards", default_value="false",
                              choices=["true", "false", "grids"],
                              description="true: an AprilGrid and a ChArUco board in place of "
                                          "tags 0 and 1 (config/demo_boards.yaml); grids: a "
                                          "chessboard and two circle grids in place of tags 0-2 "
                                          "(config/demo_grids.yaml)"),
    ]
    # one simulator and one calibrator each way: a string array parameter cannot come from a
    # launch argument's text without launch_ros guessing its type (an empty list has none)
    for value, boards, config in (
            ("false", None, "demo.yaml"),
            ("true", DEMO_BOARDS, "demo_boards.yaml"),
            ("grids", DEMO_GRIDS, "demo_grids.yaml")):
        condition = IfCondition(EqualsSubstitution(LaunchConfiguration("boards"), value))
        params = dict(sim) if boards is None else {**sim, "boards": boards}
        actions += [
            Node(
                package="rwhec_ros",
                executable="rwhec_demo_sim",
                name="rwhec_demo_sim",
                parameters=[params],
                output="screen",
                emulate_tty=True,
                condition=condition,
            ),
            Node(
                package="rwhec_ros",
                executable="calibrator",
                name="calibrator",
                parameters=[PathJoinSubstitution([share, "config", config])],
                output="screen",
                emulate_tty=True,
                condition=condition,
            ),
        ]
    return LaunchDescription(actions)
