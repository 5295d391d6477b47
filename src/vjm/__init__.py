"""vjm: virtual-joint-method stiffness of parallel machines."""
