"""The energies side: bodies and their pose maps, springs and dampers, and the scene
that sums them into a `LagrangianSystem` (with the pose-map equations)."""
