"""The thesis learners (torch): ``small_inception``, ``inception_v3``, ``inception_v3_random``
(``learner.OnlineLearner``), plug-ins of group ``tactex.learners``; ``cnn_auto`` is the
product's ladder over them (``tactex_ros/core/ladder.py``)."""
