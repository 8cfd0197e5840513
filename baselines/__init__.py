"""Classical contouring controllers as policies with Stable-Baselines3's predict signature."""
