"""``rover-env diagnose`` as a pipeline of stages over one state (:mod:`.pipeline`); the
public entry point is :mod:`rover_env.calibration.diagnose`."""
