"""signorini: convergence studies for the normal compliance model of the Signorini problem."""
__version__ = "0.1.0"
