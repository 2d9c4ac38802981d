"""The installed wheel, from outside the repository: run by scripts/test_wheel.sh
in a fresh venv where `umpnet` is only what the wheel put there."""

import sys
from pathlib import Path

import gymnasium as gym
import umpnet
import umpnet.gym  # registers umpnet/Goal-v0 and umpnet/Explore-v0

repo = Path(sys.argv[1]).resolve()
installed = Path(umpnet.__file__).resolve()
assert repo not in installed.parents, f"umpnet imported from the repository ({installed}), not the wheel"

# An Env episode: grasp where the object is, move, and the joint state changes or not, without error.
env = umpnet.Env(category="Microwave", split="test", seed=0)
obs = env.reset()
policy = umpnet.Policy.default()
assert policy.resolution == obs["image"].shape[:2], (policy.resolution, obs["image"].shape)
row, col = policy.position(obs["image"])
obs, *_ = env.step_position(row, col)
for _ in range(3):
    obs, *_ = env.step_direction([0.0, -1.0, 0.0])

# The shipped policy drives gymnasium's goal environment through Policy.act.
genv = gym.make("umpnet/Goal-v0", resolution=policy.resolution)
obs, info = genv.reset(seed=0)
assert genv.observation_space.contains(obs)
steps = 0
for _ in range(12):
    obs, reward, terminated, truncated, info = genv.step(policy.act(obs, "goal"))
    steps += 1
    if terminated or truncated:
        break
genv.close()
print(f"wheel smoke: umpnet {umpnet.__version__} from {installed.parent}; {steps} gym steps; reward {reward:.3f}")
