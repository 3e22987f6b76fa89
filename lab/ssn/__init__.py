"""SSN++ training, data preparation and evaluation."""
