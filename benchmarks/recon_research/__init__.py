"""Research comparisons of reconstruction methods (no command runs them; the benchmark
``recon_accuracy`` does, and docs/reconstruction.md keeps the results): coordinated-turn
smoother, oracle floors, robust (Student-t) smoothing, leave-one-recording-out comparisons."""
