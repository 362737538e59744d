"""A trial's life, ROS-free: its record on disk (``record``), resuming it (``resume``), sessions
of trials (``session``, ``trialfile``), the HTML reports (``report``) and the console's progress
lines (``progress``). Every entrance (the explorer node, ``tactex graph run``, the lab) uses these."""
