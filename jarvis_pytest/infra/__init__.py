"""Infrastructure: the Docker engine, device images, containers, networks, the pre-warm pool, cleanup."""
