"""robovae: a variational autoencoder over robot graphs built from MuJoCo models."""

__version__ = "0.1.0"
