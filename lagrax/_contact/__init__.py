"""Contact: spheres fixed to a system's bodies against a ground plane (see
`lagrax.contact`)."""
