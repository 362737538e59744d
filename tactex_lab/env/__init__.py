"""A Gymnasium environment over recorded presses (``touch_env.TouchEnv``): an agent chooses
the next platform to touch or STOP and is scored on being right and on the touches it spent;
tactex's own strategies and stop rule are agents in it (``agents.EngineAgent``)."""
