"""Ground-truth generation with Mitsuba 3 (pip install -e .[datagen]); see docs/ground-truth.md."""
