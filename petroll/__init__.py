"""petroll: 3-D time-dependent frictionless rolling contact of a rigid body on a viscoelastic half-space."""

__version__ = "0.1.0"
