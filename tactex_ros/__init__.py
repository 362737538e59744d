"""tactex: active tactile texture recognition; the product (ROS 2 application, torch-free core).
The thesis lab is the package ``tactex_lab`` beside it."""

__version__ = "0.1.0"
