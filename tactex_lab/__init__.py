"""The thesis lab beside the product: the CNN learners (``cnn/``), experiments and benchmarks
(``experiments/``), statistics and figures (``analysis/``) and their ``tactex`` commands
(``cli/``). It imports the product (``tactex_ros``); the product finds it only through the entry
points of ``setup.cfg`` (``tactex.learners``, ``tactex.commands``)."""
