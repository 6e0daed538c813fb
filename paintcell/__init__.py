"""paintcell: plan spray-paint coverage on car-body parts and prove it on simulated paint robots."""

__version__ = "0.1.0"
