"""What a run shows: metrics, plots and the paper's studies."""
