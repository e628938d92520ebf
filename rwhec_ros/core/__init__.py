"""ROS-free mathematics of generalized robot-world/hand-eye calibration."""
