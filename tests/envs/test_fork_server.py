"""The fork server that starts each environment episode's process: a fork of a process that has
imported foldbot and simulated nothing gives the episode a fresh interpreter would."""

import os
import signal

import numpy as np
import pytest

from foldbot.envs import TowelFlattenConfig, TowelFlattenEnv
from foldbot.envs import fork_server as fs
from foldbot.envs.episode_process import EpisodeProcess
from foldbot.envs.policies import PullPolicy
from foldbot.envs.towel_flatten import episode_config
from foldbot.errors import FoldbotError

pytestmark = pytest.mark.skipif(not fs.ForkServer.available(), reason="needs fork and pidfds")

EPISODE = episode_config(TowelFlattenConfig(resolution=5), 2)


def parent_of(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as stat:
        return int(stat.read().rsplit(")", 1)[1].split()[1])


def pulled_once(env: TowelFlattenEnv) -> tuple[dict, dict, dict]:
    """Seed 2's start, the pulls' policy's first action on it, and what the step saw."""
    obs, info = env.reset(seed=2)
    after, _reward, _term, _trunc, step = env.step(PullPolicy(env)(info))
    return obs, after, {"start": info["coverage"], "after": step["coverage"]}


def test_a_forked_episode_runs_as_one_in_a_fresh_interpreter(monkeypatch):
    env = TowelFlattenEnv(resolution=5, image_size=(48, 64))
    try:
        env.reset(seed=2)
        server = fs.ForkServer.for_entry("foldbot.envs.episode_process:serve_socket")
        child = env._episode._process
        assert isinstance(child, fs.ChildProcess) and env._episode.alive
        # A child of the server, which is ours: not this process's own child.
        assert parent_of(child.pid) == server._process.pid != os.getpid()
        assert parent_of(server._process.pid) == os.getpid()
        forked = pulled_once(env)
        assert child.ended(10.0)  # each reset ends the last episode's process
        with monkeypatch.context() as m:
            m.setattr(fs.ForkServer, "available", staticmethod(lambda: False))
            fresh = pulled_once(env)
            assert isinstance(env._episode._process, fs.InterpreterProcess)
    finally:
        env.close()
    # The same crumpled towel, pulled the same, seen the same, to the bit.
    assert forked[2] == fresh[2]
    for seen, again in zip(forked[:2], fresh[:2], strict=True):
        np.testing.assert_array_equal(seen["rgb"], again["rgb"])
        np.testing.assert_array_equal(seen["depth"], again["depth"])


def test_a_server_that_died_is_started_again():
    entry = "foldbot.envs.episode_process:serve_socket"
    first = fs.ForkServer.for_entry(entry)
    assert fs.ForkServer.for_entry(entry) is first  # one per process and entry
    first._process.send_signal(signal.SIGKILL)
    first._process.wait(10.0)
    second = fs.ForkServer.for_entry(entry)
    assert second is not first
    episode = EpisodeProcess(EPISODE)
    try:
        assert parent_of(episode._process.pid) == second._process.pid
    finally:
        episode.close()


def test_a_killed_episode_is_reported_ended():
    episode = EpisodeProcess(EPISODE)
    child = episode._process
    child.kill()
    assert child.ended(10.0) and not episode.alive
    with pytest.raises(FoldbotError, match=r"the episode.s process ended during its step$"):
        episode.step("pick_and_place", np.zeros(2), np.zeros(2))
    episode.close()
    episode.close()  # twice is allowed
