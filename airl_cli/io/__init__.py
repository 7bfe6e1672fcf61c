"""The files airl reads and writes: the dataset file and its checks, the multi-model MDP benchmark
files, atomic writes and run folders. No Hydra, no console."""
