"""tactex: active tactile texture recognition (ROS 2 application with a ROS-free core)."""

__version__ = "0.1.0"
