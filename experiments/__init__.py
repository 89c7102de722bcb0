"""Entry points: Hydra wiring (config schemas, the run job), the Rerun recording, reproduction and benchmarks."""
