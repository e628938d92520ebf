"""rwhec_ros.sync"""
