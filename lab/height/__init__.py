"""Learned cutout pixel-height predictor: data generator, training and evaluation."""
