"""Analysis of results, no ROS and no experiment running: statistics (``stats.py``), every
figure (``charts.py``) and the sim-to-real report (``sim_vs_real.py``)."""
