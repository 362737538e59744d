"""The thesis learners (torch): ``small_inception``, ``inception_v3``, ``inception_v3_random``
(``learner.OnlineLearner``) and ``cnn_auto`` (``auto.AutoLearner``), plug-ins of group
``tactex.learners``."""
