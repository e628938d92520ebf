"""rwhec_ros.vision"""
