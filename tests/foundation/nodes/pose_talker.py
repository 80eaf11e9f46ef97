"""Test node: publishes turtlesim/msg/Pose on /pose at 20 Hz and serves /set_pen (turtlesim/srv/SetPen)."""
import sys

import rclpy
from rclpy.node import Node
from turtlesim.msg import Pose
from turtlesim.srv import SetPen


class Talker(Node):
    def __init__(self) -> None:
        super().__init__("pose_talker")
        self.pub = self.create_publisher(Pose, "pose", 10)
        self.n = 0
        self.create_timer(0.05, self.tick)
        self.create_service(SetPen, "set_pen", self.on_set_pen)

    def tick(self) -> None:
        self.n += 1
        self.pub.publish(Pose(x=float(self.n), y=2.5, theta=0.5))

    def on_set_pen(self, req: SetPen.Request, resp: SetPen.Response) -> SetPen.Response:
        print(f"set_pen r={req.r} g={req.g} b={req.b} width={req.width} off={req.off}", flush=True)
        return resp


def main() -> None:
    rclpy.init()
    node = Talker()
    print("talker ready", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    sys.exit(0)


if __name__ == "__main__":
    main()
