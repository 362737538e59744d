"""The robot domain, torch-free and ROS-free: the scene (``scene.py``), the press state machine
and the mock arm's spring-damper physics (``press.py``), robot profiles (``robots.py``) and
sensor profiles (``sensors.py``). Imports ``core`` and ``paths`` only."""
