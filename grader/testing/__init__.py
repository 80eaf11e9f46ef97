"""Helpers for testing with a live ROS graph and with bags (also a pytest plugin)."""
