"""Publishes /ticks about every 0.5 s of wall time: the timeout of spin_once paces it, which no
ROS clock follows (and no `time` call shows)."""

import rclpy
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import String


def main():
    rclpy.init()
    node = rclpy.create_node("spinner")
    pub = node.create_publisher(String, "ticks", 10)
    try:
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.5)
            pub.publish(String(data="tick"))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
