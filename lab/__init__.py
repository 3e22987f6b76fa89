"""pixgraph lab: ground-truth generation, metrics, benchmarks and training (not needed at run time)."""
