"""Fixtures of the rclpy tests (each module skips itself without rclpy)."""

import pytest


@pytest.fixture
def context():
    """A fresh rclpy context, shut down after the test."""
    rclpy = pytest.importorskip("rclpy")
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)
