"""rwhec_ros.data"""
