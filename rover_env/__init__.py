"""rover_env: simulator, Gymnasium environment and calibration toolkit for the Proto-Explorer rover."""

__version__ = "0.1.0"
