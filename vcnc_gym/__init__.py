"""vcnc-gym: Gymnasium environments for contouring control of CNC feed drives."""

__version__ = "0.1.0"
