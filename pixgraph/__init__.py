"""pixgraph: a node-graph compositing engine. It knows nothing of shadows or images."""
__version__ = "0.1.0"
