"""Design in the latent space: variations, paths and optimisation of robots."""
