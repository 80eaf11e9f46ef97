"""Publishes /ticks at 2 Hz from a ROS timer: follows /clock."""

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_msgs.msg import String


class Ticker(Node):
    def __init__(self):
        super().__init__("ticker")
        self.pub = self.create_publisher(String, "ticks", 10)
        self.create_timer(0.5, self.tick)
        self.get_logger().info("ticker up")     # once, in the constructor (a greeting)

    def tick(self):
        self.pub.publish(String(data="tick"))


def main():
    rclpy.init()
    node = Ticker()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
