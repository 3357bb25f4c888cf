"""Design sweeps: sampling design points, running them in batches, storing, ranking, plotting."""
