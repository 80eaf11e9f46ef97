"""Publishes '<greeting> x<repeat> from <node name>' on `chatter` at 10 Hz (parameters show up in
the messages, so a test can see which parameters and remappings the launch file applied)."""
import rclpy
from rclpy.node import Node
from std_msgs.msg import String


class Talker(Node):
    def __init__(self):
        super().__init__("talker")
        self.declare_parameter("greeting", "unset")
        self.declare_parameter("repeat", 0)
        self.pub = self.create_publisher(String, "chatter", 10)
        self.create_timer(0.1, self.tick)

    def tick(self):
        greeting = self.get_parameter("greeting").value
        repeat = self.get_parameter("repeat").value
        self.pub.publish(String(data=f"{greeting} x{repeat} from {self.get_fully_qualified_name()}"))


def main():
    rclpy.init()
    node = Talker()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
