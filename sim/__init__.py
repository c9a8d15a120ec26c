"""PyBullet worlds and simulated motor controllers on CAN."""
