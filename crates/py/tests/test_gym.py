"""The gymnasium environments: the env checker, rewards that pay the oracle
and not random, the step budget and info, and the observation the shipped
policy needs."""

from pathlib import Path

import numpy as np
import pytest
import umpnet

RES = (48, 64)


def test_gymnasium_check_env():
    import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
    import umpnet.gym  # noqa: F401  (registers the ids)
    from gymnasium.utils.env_checker import check_env

    env = gym.make("umpnet/Explore-v0", resolution=RES, category=["Door"]).unwrapped
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs["phase"] == 0 and "scene" in info
    obs, _r, _term, _trunc, info = env.step({"phase": 0, "pixel": np.array([24, 32]), "direction": np.zeros(3)})
    assert obs["phase"] == 1


def _gym_returns(env_id, policy, episodes=6):
    import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
    import umpnet.gym  # noqa: F401  (registers the ids)

    env = gym.make(env_id, resolution=RES, category=["Door", "StorageFurniture", "Microwave"])
    rng = np.random.default_rng(0)
    returns, successes = [], []
    for k in range(episodes):
        env.reset(seed=k)
        total, done, info = 0.0, False, {}
        inner = env.unwrapped._env
        while not done:
            phase = env.unwrapped._phase
            if policy == "oracle":
                a = inner.scripted_action("oracle")
                if a is None:
                    break
            else:
                a = inner.scripted_action("random") if phase == 0 else rng.normal(size=3)
            action = {"phase": phase, "pixel": np.zeros(2, dtype=np.int64), "direction": np.zeros(3, dtype=np.float32)}
            if phase == 0:
                action["pixel"] = np.array(a)
            else:
                action["direction"] = np.asarray(a, dtype=np.float32)
            _, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        returns.append(total)
        successes.append(bool(info.get("success")))
    return np.mean(returns), np.mean(successes)


@pytest.mark.parametrize("env_id", ["umpnet/Goal-v0", "umpnet/Explore-v0"])
def test_gym_rewards_pay_the_oracle_and_not_random(env_id):
    oracle, oracle_success = _gym_returns(env_id, "oracle")
    random, _ = _gym_returns(env_id, "random")
    assert oracle > 1.0, oracle
    assert oracle > random + 1.0, (oracle, random)
    # The oracle reaches the goal, or (exploring) a joint limit, which ends the episode.
    assert oracle_success >= (0.8 if env_id == "umpnet/Goal-v0" else 0.5), oracle_success


def test_gym_budget_and_info():
    import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
    import umpnet.gym  # noqa: F401

    env = gym.make("umpnet/Explore-v0", resolution=RES, category=["Kettle"])
    assert env.spec.max_episode_steps == 16
    _, info = env.reset(seed=1)
    assert info["success"] is False and info["elapsed_steps"] == 0
    assert env.unwrapped._budget() == 3  # the paper's budget for a Kettle


def test_a_gym_observation_carries_the_gripper_pixel_the_shipped_policy_needs():
    import gymnasium as gym

    shipped = str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small")
    policy = umpnet.Policy(shipped, seed=0)
    env = gym.make("umpnet/Goal-v0", resolution=policy.resolution, category=["Door"])
    obs, _ = env.reset(seed=1)
    assert tuple(obs["gripper_pixel"]) == (-1, -1) and env.observation_space.contains(obs)
    row, col = policy.position(obs["image"], obs["reference"])
    grasp = {"phase": 0, "pixel": np.array([row, col]), "direction": np.zeros(3, np.float32)}
    obs, _, terminated, _, info = env.step(grasp)
    assert info["valid"] and not terminated, info
    # The gripper is where the policy grasped (the suction point, projected back).
    assert np.abs(obs["gripper_pixel"] - [row, col]).max() <= 2, (obs["gripper_pixel"], (row, col))
    np.testing.assert_array_equal(obs["gripper_pixel"], env.unwrapped._obs["gripper_pixel"])
    assert env.observation_space.contains(obs)
    # With it, the policy's direction comes from public observation fields alone.
    decision = policy.direction_batch(
        obs["image"][None], obs["reference"][None], obs["gripper_pixel"][None], mode="goal"
    )[0]
    obs, *_ = env.step({"phase": 1, "pixel": np.zeros(2, np.int64), "direction": np.asarray(decision["direction"])})
    assert env.observation_space.contains(obs)
