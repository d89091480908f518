"""How things move, one module per physics: the paper's lattice steps, and active Brownian
motion in SI units."""
