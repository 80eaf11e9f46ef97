"""Publishes 'console script' on /styles/py at 10 Hz."""
import rclpy
from std_msgs.msg import String


def main():
    rclpy.init()
    node = rclpy.create_node("py_talker")
    pub = node.create_publisher(String, "/styles/py", 10)
    node.create_timer(0.1, lambda: pub.publish(String(data="console script")))
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
