"""PyTorch training for UMPNet against the umpnet Rust environments."""

# torch loads its own LLVM (through triton) lazily, on the first optimizer or
# compile. If Mesa's lavapipe (umpnet's wgpu renderer on CPU-only machines)
# has already loaded LLVM 15 in the process, that lazy load segfaults; the
# other order is safe. So load torch's part first, before any environment.
import torch
import torch._dynamo  # noqa: F401
