"""Model: tree-GRU encoder and decoder, the VAE loss and the RoboVAE LightningModule."""
