"""The development runner: ``tactex graph run`` starts the described graph (``ros/graph.py``)
as real ROS 2 processes without ``launch`` (``launcher.py``: start, supervise, stop, the run's
outcome) and runs a study session on it (``session_runner.py``: the operator's console).
Robot deployments start the same nodes with ``ros2 launch tactex explore.launch.py``."""
