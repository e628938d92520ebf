"""rwhec_ros: certifiably globally optimal multi-sensor extrinsic calibration (ROS 2, Python).

The core (``rwhec_ros.core``, ``vision``, ``sync``, ``data``, ``session``, ``cli``) never imports
rclpy; the ROS layer lives in ``rwhec_ros.ros``.
"""

__version__ = "0.1.0"
