"""Model files read into trees: URDF (parsed here) and MJCF (through MuJoCo's compiler)."""
