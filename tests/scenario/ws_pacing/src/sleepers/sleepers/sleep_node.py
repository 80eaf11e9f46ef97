"""Publishes /ticks at 2 Hz of wall time with time.sleep."""

import time

import rclpy
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import String


def main():
    rclpy.init()
    node = rclpy.create_node("sleeper")
    pub = node.create_publisher(String, "ticks", 10)
    try:
        while rclpy.ok():
            pub.publish(String(data="tick"))
            time.sleep(0.5)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
