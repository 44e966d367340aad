"""System 2: layered swimming (Yang, Laszlo, Singh 2004)."""
