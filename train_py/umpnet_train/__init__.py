"""PyTorch training for UMPNet against the umpnet Rust environments."""
