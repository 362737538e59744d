"""Everything that imports rclpy or ROS messages: message conversions (``adapter.py``), node
settings (``settings.py``), the graph description (``graph.py``), the process launcher that
starts it without ``launch`` (the development runner, ``devrun/``), MCAP bags (``bag.py``), the action goal helper
(``goal.py``) and the nodes (``nodes/``)."""
