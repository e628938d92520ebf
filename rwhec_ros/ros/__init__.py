"""rwhec_ros.ros"""
