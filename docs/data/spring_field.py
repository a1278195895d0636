"""Vector field of spring.toml: a mass on a hardening spring with viscous friction (H. K. Khalil, Nonlinear
Systems, 3rd ed., Sec. 1.2.3): m ÿ + c ẏ + k (1 + a² y²) y = u, states (y, ẏ), input the force u."""

import numpy as np

M, C, K, A = 1.0, 0.4, 1.0, 1.0  # kg, N s/m, N/m, 1/m


def field(x, u):
    """x: (runs, 2) positions and velocities; u: (runs, 1) forces; returns (runs, 2) their derivatives."""
    y, v = x[:, 0], x[:, 1]
    return np.stack([v, (u[:, 0] - C * v - K * (1.0 + A**2 * y**2) * y) / M], axis=1)
