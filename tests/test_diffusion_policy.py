"""The diffusion policy (agents.learned): features, DART data, training, resume, saving and
acting in single and vectorised envs, and the CLI's errors. Tiny sizes: nothing here says
how well a policy does (benchmarks/learning.py measures that)."""

from __future__ import annotations

import dataclasses
import json
import os
import signal

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import torch  # noqa: E402

import slide_gym  # noqa: E402,F401 - registers the environments
from agents.learned.data import ChunkSampler, chunk_to_actions, load_demonstrations  # noqa: E402
from agents.learned.diffusion import DiffusionConfig, DiffusionModel  # noqa: E402
from agents.learned.features import task_features  # noqa: E402
from agents.learned.policy import DiffusionPolicy  # noqa: E402
from agents.learned.train import (  # noqa: E402
    TrainConfig,
    hand_kind,
    read_progress,
    train_diffusion,
)
from slide_gym.cli import main  # noqa: E402
from slide_gym.datasets.config import CollectConfig  # noqa: E402
from slide_gym.datasets.recording import CHUNK_KEY, LABEL_KEY  # noqa: E402
from slide_gym.datasets.store import load, read_episodes  # noqa: E402

torch.set_num_threads(1)

ENV_ID = "SlideGym/TopSlide-v0"
DATASET = "test/dart-slide-v0"
NOISE = 0.05
TINY = DiffusionConfig(channels=(16, 32), step_embed_dim=16, train_steps=20, inference_steps=4)


@pytest.fixture(scope="module")
def dart(minari_root):
    """2 expert slide episodes with DART noise (seeds 4, 5; with this noise the expert's
    seed 3 pushes the plate off the table)."""
    args = ["collect", "--env", ENV_ID, "--episodes", "2", "--seed", "4", "--workers", "1"]
    args += ["--time-budget", "60", "--action-noise", str(NOISE), "--dataset-id", DATASET]
    assert main(args) == 0
    return load(DATASET)


def _config(iterations: int, log_every: int = 10) -> TrainConfig:
    return TrainConfig(
        iterations=iterations,
        batch_size=32,
        learning_rate=3e-3,
        warmup=5,
        log_every=log_every,
        val_episodes=0,
    )


def _train(dataset, out, iterations, log_every=10, resume=False):
    return train_diffusion(
        dataset,
        out,
        config=TINY,
        train=_config(iterations, log_every),
        env_id=ENV_ID,
        env_kwargs={"object": "square", "table": "square"},
        card={"dataset_id": DATASET},
        resume=resume,
        progress=False,
    )


@pytest.fixture(scope="module")
def trained(dart, tmp_path_factory):
    out = tmp_path_factory.mktemp("dp") / "run"
    _train(dart, out, 200, log_every=40)
    return out


def test_dart_labels_are_the_experts_clean_actions(dart):
    """The executed actions are noisy; the labels are what a fresh expert with the same seed
    answers to the same observations (it reads nothing else) when it carries on from the
    executed actions, and the noise is seeded."""
    from agents.planner_agent import PlannerAgent

    for ep in read_episodes(dart):
        labels = ep.infos[LABEL_KEY][1:]
        executed = ep.actions
        assert labels.shape == executed.shape
        arm = np.abs(labels[:, :7] - executed[:, :7])
        assert arm.mean() > NOISE / 4  # the noise moved the executed arm actions ...
        np.testing.assert_array_equal(labels[:, 7], executed[:, 7])  # ... not the hand
        agent = PlannerAgent("regions", 60.0, seed=ep.seed)
        try:
            for t in range(len(labels)):
                obs = {k: v[t] for k, v in ep.observations.items()}
                action, _ = agent.predict(obs, episode_start=np.array([t == 0]))
                np.testing.assert_array_equal(action, labels[t])
                if not np.array_equal(executed[t], labels[t]):
                    agent.expert(0).follow(executed[t], retime=False)
        finally:
            agent.close()


def test_dart_noise_in_some_phases_is_corrected_by_the_next_label(minari_root):
    """With ``--noise-phases transfer`` only the move to the grasp is noisy, and the expert
    carries on from each executed action: its next label takes the noise back (without
    that, the executed arm drifts from the plan by the sum of the noise)."""
    args = ["collect", "--env", "SlideGym/TopSlideGrasp-v0", "--episodes", "1", "--seed", "4"]
    args += ["--workers", "1", "--action-noise", "0.1", "--noise-phases", "transfer"]
    assert main([*args, "--dataset-id", "test/dart-transfer-v0"]) == 0
    ep = next(read_episodes(load("test/dart-transfer-v0")))
    assert ep.record["success"]
    labels, executed = ep.infos[LABEL_KEY][1:], ep.actions
    noise = executed[:, :7] - labels[:, :7]
    noisy = np.flatnonzero(np.abs(noise).max(axis=1) > 0)
    start = dict(ep.record["phase_steps"])["transfer"]
    assert len(noisy) > 20 and noisy[0] == start  # the transfer, none of the slide
    assert np.array_equal(noisy, np.arange(start, start + len(noisy)))  # and nothing after it
    t = noisy[1:-2]  # the label after a noisy step undoes that step's noise
    change = labels[t + 1, :7] - labels[t, :7]
    assert np.corrcoef(noise[t].ravel(), change.ravel())[0, 1] < -0.5
    for bad, why in (("fly", "noise_phases must name"), ("approach", "needs an action_noise")):
        with pytest.raises(ValueError, match=why):
            CollectConfig(
                env_id=ENV_ID, noise_phases=[bad], action_noise=0.3 if bad == "fly" else 0.0
            )


def test_a_collection_without_noise_keeps_its_identity():
    """``action_noise`` is in a configuration's JSON only when set, so collections made before
    DART existed resume (their cases keep their keys) and DART ones differ from them."""
    plain = CollectConfig(env_id=ENV_ID)
    assert "action_noise" not in plain.to_json()
    assert CollectConfig.from_json(plain.to_json()) == plain
    noisy = CollectConfig(env_id=ENV_ID, action_noise=NOISE)
    assert noisy.to_json()["action_noise"] == NOISE
    assert noisy.differences(plain) == [f"action_noise: {NOISE!r} != 0.0"]


def test_features_read_the_envs_overhang(dart):
    ep = next(read_episodes(dart))
    feats = task_features(ep.observations)
    np.testing.assert_allclose(feats[:, -1], ep.infos["overhang_m"], atol=1e-4)  # 0.1 mm
    assert np.all(feats[:, 5] > 0)  # the plate's centroid stays on the table
    np.testing.assert_allclose(np.linalg.norm(feats[:, 6:8], axis=1), 1.0, atol=1e-6)


def test_windows_clamp_at_the_start_and_pad_at_the_end(dart):
    demos = load_demonstrations(dart, with_features=False)
    assert demos.episodes == 2 and np.array_equal(
        demos.labels[: demos.lengths[0]], dart[0].infos[LABEL_KEY][1:]
    )
    sampler = ChunkSampler(demos, obs_horizon=2, pred_horizon=16, representation="deltas")
    assert len(sampler) == demos.frames
    first_obs = sampler.inputs[sampler.obs_rows[0]]
    np.testing.assert_array_equal(first_obs[0], first_obs[1])  # the first input repeats
    np.testing.assert_array_equal(sampler.chunks[0, 1:], demos.labels[:15])
    assert np.all(sampler.chunks[0, 0, :7] == 0)  # before the start: no motion
    last = demos.lengths[0] - 1
    tail = sampler.chunks[last]
    np.testing.assert_array_equal(tail[1], demos.labels[last])
    assert np.all(tail[2:, :7] == 0)  # past the end: the arm holds still ...
    assert np.all(tail[2:, 7] == demos.labels[last, 7])  # ... and the hand keeps its command


def test_offset_chunks_give_back_the_actions(dart):
    """Offsets are the running sum of the increments from the current step; turned back into
    actions they are the labels."""
    demos = load_demonstrations(dart, with_features=False)
    offsets = ChunkSampler(demos, 2, 16, representation="offsets")
    deltas = ChunkSampler(demos, 2, 16, representation="deltas")
    for w in (0, 5, demos.lengths[0] - 3, demos.lengths[0] + 7):
        assert np.all(offsets.chunks[w, 0, :7] == 0)  # the target before the current step
        got = chunk_to_actions(offsets.chunks[w], 1, 8, "offsets")
        np.testing.assert_allclose(got, deltas.chunks[w, 1:9], atol=1e-5)
        plain = chunk_to_actions(deltas.chunks[w], 1, 8, "deltas")
        np.testing.assert_array_equal(plain, deltas.chunks[w, 1:9])


def test_training_lowers_the_loss_and_writes_its_files(trained):
    rows = read_progress(trained / "progress.csv")
    assert [int(r["iteration"]) for r in rows] == [40, 80, 120, 160, 200]
    assert float(rows[-1]["loss"]) < 0.8 * float(rows[0]["loss"])
    for name in ("checkpoint.pt", "policy.pt", "policy.json", "learning_curve.png"):
        assert (trained / name).is_file()
    card = json.loads((trained / "policy.json").read_text())
    assert card["env_id"] == ENV_ID and card["demonstrations"]["episodes"] == 2
    assert card["checkpoint"]["iteration"] == 200


def test_interrupted_training_resumes_bit_for_bit(dart, tmp_path, monkeypatch):
    straight = tmp_path / "straight"
    _train(dart, straight, 40)
    stopped = tmp_path / "stopped"
    calls = {"n": 0}
    real = torch.optim.AdamW.step

    def stop_at_25(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 25:
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of iteration 25
        return real(self, *args, **kwargs)

    monkeypatch.setattr(torch.optim.AdamW, "step", stop_at_25)
    with pytest.raises(KeyboardInterrupt):
        _train(dart, stopped, 40)
    monkeypatch.setattr(torch.optim.AdamW, "step", real)
    with pytest.raises(ValueError, match="--resume"):
        _train(dart, stopped, 40)  # a run folder is never overwritten by accident
    blob = torch.load(stopped / "checkpoint.pt", weights_only=False)
    assert blob["iteration"] == 25
    _train(dart, stopped, 40, resume=True)
    a = torch.load(straight / "checkpoint.pt", weights_only=False)
    b = torch.load(stopped / "checkpoint.pt", weights_only=False)
    for key in a["ema"]["model"]:
        torch.testing.assert_close(a["ema"]["model"][key], b["ema"]["model"][key])
    rows = read_progress(stopped / "progress.csv")
    assert [int(r["iteration"]) for r in rows] == [10, 20, 30, 40]


def test_policy_predicts_single_batched_and_deterministically(trained):
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    policy = DiffusionPolicy.load(trained, seed=1)
    action, state = policy.predict(obs, episode_start=np.array([True]))
    assert action.shape == (8,) and action.dtype == np.float32 and state is None
    assert np.all(np.abs(action) <= 1)
    batch = {k: np.stack([v] * 3) for k, v in obs.items()}
    actions, _ = DiffusionPolicy.load(trained, seed=1).predict(batch, episode_start=np.ones(3))
    assert actions.shape == (3, 8)
    again, _ = DiffusionPolicy.load(trained, seed=1).predict(obs, episode_start=np.array([True]))
    np.testing.assert_array_equal(action, again)


def test_a_binary_hand_keeps_its_scale_and_is_executed_as_open_or_closed(trained, monkeypatch):
    labels = np.zeros((4, 8))
    labels[:, -1] = [-1, -1, 1, np.nan]  # a dropped DAgger label does not count
    assert hand_kind(labels) == "binary"
    labels[0, -1] = 0.2
    assert hand_kind(labels) == "continuous"
    # closed in 1 step of 20: standardising would put a close at +4.4 sd; binary keeps +1
    chunk = torch.full((16, 8), -1.0)
    chunk_mean, chunk_std = chunk.clone(), torch.ones(16, 8)
    chunk_mean[:, -1], chunk_std[:, -1] = -0.9, 0.436
    for hand, close in (("continuous", 4.358), ("binary", 1.0)):
        config = DiffusionConfig(channels=(16, 32), scaling="standard", hand=hand)
        model = DiffusionModel(config, 3, 8)
        model.set_stats(torch.zeros(3), torch.ones(3), chunk_mean, chunk_std, chunk, -chunk)
        closed = model.normalize_action(torch.ones(1, 16, 8))[0, 0, -1]
        assert float(closed) == pytest.approx(close, abs=1e-3)
    policy = DiffusionPolicy.load(trained)
    assert policy.config.hand == "binary"  # the expert's hand commands are -1 or +1
    sampled = torch.full((1, 16, 8), 0.0)
    sampled[0, :, -1] = torch.linspace(-0.9, 0.9, 16)
    monkeypatch.setattr(policy.model, "sample", lambda *a: sampled)
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    hands = [policy.predict(obs, episode_start=np.array([i == 0]))[0][-1] for i in range(8)]
    assert set(hands) <= {-1.0, 1.0} and hands[0] == -1.0 and hands[-1] == 1.0


def test_action_queue_runs_eight_steps_and_resets_at_episode_start(trained, monkeypatch):
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    policy = DiffusionPolicy.load(trained)
    calls = []
    real = policy.model.sample
    monkeypatch.setattr(policy.model, "sample", lambda *a: calls.append(1) or real(*a))
    policy.predict(obs, episode_start=np.array([True]))
    for _ in range(7):
        policy.predict(obs, episode_start=np.array([False]))
    assert len(calls) == 1  # one chunk, 8 actions executed
    policy.predict(obs, episode_start=np.array([False]))
    assert len(calls) == 2  # the queue ran dry
    policy.predict(obs, episode_start=np.array([True]))
    assert len(calls) == 3  # a new episode drops what was queued


def test_a_shorter_action_horizon_samples_more_often(trained, monkeypatch):
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    policy = DiffusionPolicy.load(trained, action_horizon=2)
    calls = []
    real = policy.model.sample
    monkeypatch.setattr(policy.model, "sample", lambda *a: calls.append(1) or real(*a))
    for t in range(8):
        policy.predict(obs, episode_start=np.array([t == 0]))
    assert len(calls) == 4
    most = policy.config.pred_horizon - policy.config.obs_horizon + 1
    for bad in (0, most + 1, 2.0):
        with pytest.raises(ValueError, match="action_horizon"):
            DiffusionPolicy.load(trained, action_horizon=bad)


def test_zero_noise_scale_samples_the_same_chunk_whatever_the_seed(trained):
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()

    def first_action(seed: int, noise_scale: float) -> np.ndarray:
        policy = DiffusionPolicy.load(trained, seed=seed, noise_scale=noise_scale)
        return policy.predict(obs, episode_start=np.array([True]))[0]

    np.testing.assert_array_equal(first_action(0, 0.0), first_action(1, 0.0))
    assert not np.array_equal(first_action(0, 1.0), first_action(1, 1.0))
    for bad in (-0.1, 1.5, float("nan"), True):
        with pytest.raises(ValueError, match="noise_scale"):
            DiffusionPolicy.load(trained, noise_scale=bad)


def test_inference_steps_change_the_sampled_chunk(trained):
    """The DDIM steps per chunk are a sampling choice of the loaded policy: with the same
    seed, 1 and the model's own 10 give different chunks; 10 given explicitly, the same."""
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()

    def first_action(**kwargs: int) -> np.ndarray:
        policy = DiffusionPolicy.load(trained, seed=0, **kwargs)
        return policy.predict(obs, episode_start=np.array([True]))[0]

    own = first_action()
    steps = DiffusionPolicy.load(trained).config.inference_steps
    np.testing.assert_array_equal(first_action(inference_steps=steps), own)
    assert not np.array_equal(first_action(inference_steps=1), own)
    for bad in (0, 101, 2.0, True):
        with pytest.raises(ValueError, match="inference_steps"):
            DiffusionPolicy.load(trained, inference_steps=bad)


def test_samples_execute_the_medoid_of_the_drawn_chunks(trained):
    """With K samples the policy executes the drawn chunk whose executed entries lie nearest
    the other K - 1; with 1 it acts exactly as by default."""
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    start = np.array([True])
    default = DiffusionPolicy.load(trained, seed=3)
    np.testing.assert_array_equal(
        DiffusionPolicy.load(trained, seed=3, samples=1).predict(obs, episode_start=start)[0],
        default.predict(obs, episode_start=start)[0],
    )

    k = 6
    policy = DiffusionPolicy.load(trained, seed=3, samples=k)
    action = policy.predict(obs, episode_start=start)[0]
    # the same draws, by hand: the seeded generator's K chunks for this window
    model, config = policy.model, policy.config
    window = torch.from_numpy(np.stack(policy._history[0]))[None]
    drawn = model.sample(
        window.repeat_interleave(k, dim=0), torch.Generator().manual_seed(3), None, 1.0
    )
    first, count = config.obs_horizon - 1, policy.action_horizon
    executed = model.normalize_action(drawn)[:, first : first + count].flatten(1).numpy()
    spread = np.linalg.norm(executed[:, None] - executed[None], axis=-1).sum(axis=1)
    medoid = int(np.argmin(spread))
    assert spread[medoid] < np.max(spread)  # the draws differ, so the choice means something
    expected = chunk_to_actions(drawn[medoid].numpy(), first, count, config.actions)[0]
    if config.hand == "binary":
        expected[-1] = 1.0 if expected[-1] > 0.0 else -1.0
    np.testing.assert_allclose(action, np.clip(expected, -1.0, 1.0), atol=1e-6)
    for bad in (0, 65, 2.0, True):
        with pytest.raises(ValueError, match="samples"):
            DiffusionPolicy.load(trained, samples=bad)


def test_runs_under_sb3_evaluate_policy_on_a_vectorised_env(trained):
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    venv = make_vec_env(ENV_ID, n_envs=2, env_kwargs={"max_episode_steps": 12})
    try:
        rewards, lengths = evaluate_policy(
            DiffusionPolicy.load(trained), venv, n_eval_episodes=2, return_episode_rewards=True
        )
    finally:
        venv.close()
    assert len(rewards) == 2 and all(n <= 12 for n in lengths)


def test_evaluate_command_runs_a_policy_folder(trained, capsys):
    args = ["evaluate", str(trained), "--env", ENV_ID, "--episodes", "1", "--json"]
    assert main([*args]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["episodes"] == 1 and result["env_kwargs"]["object"] == "square"
    assert "action_horizon" not in result
    assert main([*args, "--action-horizon", "4"]) == 0
    assert json.loads(capsys.readouterr().out)["action_horizon"] == 4
    assert main([*args, "--noise-scale", "0.5"]) == 0
    assert json.loads(capsys.readouterr().out)["noise_scale"] == 0.5
    assert main([*args, "--noise-scale", "2"]) == 2
    err = capsys.readouterr().err
    assert "noise_scale" in err and len(err.strip().splitlines()) == 1
    assert main([*args, "--inference-steps", "3"]) == 0
    assert json.loads(capsys.readouterr().out)["inference_steps"] == 3
    assert main([*args, "--inference-steps", "0"]) == 2
    err = capsys.readouterr().err
    assert "inference_steps" in err and len(err.strip().splitlines()) == 1
    assert main([*args, "--samples", "3"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] == 3
    assert main([*args, "--samples", "0"]) == 2
    err = capsys.readouterr().err
    assert "samples" in err and len(err.strip().splitlines()) == 1


def test_train_dp_init_starts_from_a_policys_weights(dart, trained, tmp_path, capsys):
    out = tmp_path / "ft"
    args = ["train-dp", DATASET, "--out", str(out), "--init", str(trained)]
    assert main([*args, "--iterations", "1", "--val-episodes", "0", "--log-every", "1"]) == 0
    capsys.readouterr()
    assert json.loads((out / "policy.json").read_text())["init"] == str(trained)
    before = torch.load(trained / "policy.pt", weights_only=False)["state_dict"]
    after = torch.load(out / "policy.pt", weights_only=False)["state_dict"]
    # one step from the trained weights moves them a little, not to a fresh network's
    change = max(float((before[k] - after[k]).abs().max()) for k in before)
    assert 0 < change < 0.05


def test_one_dagger_round_adds_labelled_steps(dart, trained, tmp_path):
    from agents.learned.dagger import DAGGER_SEED, DaggerConfig, run_dagger

    config = DaggerConfig(rounds=1, episodes=1, iterations=20, max_steps=24, label_budget=60.0)
    summary = run_dagger(trained, tmp_path / "dagger", "test/dagger-v0", config, workers=1)
    (row,) = summary["rounds"]
    assert row["round"] == 1 and row["episodes"] == 1 and row["labelled_steps"] == 24
    assert row["label_queries"] == 1  # one expert keeps its plan while the learner approaches
    assert row["dataset_episodes"] == 3  # the 2 demonstrations and the learner's episode
    aggregate = load("test/dagger-v0")
    eps = list(read_episodes(aggregate))
    assert [e.record.get("dagger_round", 0) for e in eps] == [0, 0, 1]
    metas = list(aggregate.storage.get_episode_metadata([0, 1, 2]))
    assert [int(m["dagger_round"]) for m in metas] == [0, 0, 1]
    rollout = eps[2]
    assert rollout.seed == DAGGER_SEED and len(rollout.actions) == 24
    labels = rollout.infos[LABEL_KEY][1:]
    assert np.isfinite(labels).all()  # every query planned
    assert not np.array_equal(labels, rollout.actions)  # the learner acted, the expert labelled
    assert (tmp_path / "dagger" / "round-1" / "policy" / "policy.pt").is_file()
    # the round retrains with the base's batch size and AdamW settings, not the defaults
    card = json.loads((tmp_path / "dagger" / "round-1" / "policy" / "policy.json").read_text())
    base = json.loads((trained / "policy.json").read_text())["training"]
    for key in ("batch_size", "learning_rate", "warmup"):
        assert card["training"][key] == base[key], key
    assert card["training"]["batch_size"] == 32 and card["training"]["iterations"] == 20
    # the same command again resumes: nothing left to run, same figures
    again = run_dagger(trained, tmp_path / "dagger", "test/dagger-v0", config, workers=1)
    assert again["rounds"][0]["labelled_steps"] == 24


def test_a_dagger_round_with_chunk_labels_trains_on_those_windows_only(dart, trained, tmp_path):
    from agents.learned.dagger import DaggerConfig, run_dagger

    config = DaggerConfig(
        rounds=1, episodes=1, iterations=20, max_steps=24, label_budget=60.0, chunk_every=4
    )
    summary = run_dagger(trained, tmp_path / "dagger", "test/dagger-chunks-v0", config, workers=1)
    (row,) = summary["rounds"]
    assert row["chunk_queries"] == 6 and row["chunk_failures"] == 0  # steps 0, 4, ..., 20
    aggregate = load("test/dagger-chunks-v0")
    eps = list(read_episodes(aggregate))
    rollout = eps[2]
    chunks = rollout.infos[CHUNK_KEY][1:]
    assert chunks.shape == (24, 15, 8)  # chunks of 16 from an observation horizon of 2
    asked = np.isfinite(chunks).all(axis=(1, 2))
    assert np.array_equal(np.flatnonzero(asked), np.arange(0, 24, 4))
    # the chunk starts with the step's per-step label: the expert's action from that state
    labels = rollout.infos[LABEL_KEY][1:]
    assert np.allclose(chunks[asked][:, 0], labels[asked])
    assert np.isnan(eps[0].infos[CHUNK_KEY]).all()  # a demonstration has none
    demos = load_demonstrations(aggregate)
    sampler = ChunkSampler(demos, obs_horizon=2, pred_horizon=16, representation="deltas")
    demo_windows = int(demos.lengths[:2].sum())
    assert len(sampler) == demo_windows + 6  # the rollout gives its 6 labelled steps only
    rollout_chunks = sampler.chunks[demo_windows:]
    assert np.allclose(rollout_chunks[:, 1:], chunks[asked])
    # before the step: the action executed (none at the episode's start)
    executed = np.asarray(rollout.actions, np.float32)
    assert np.allclose(rollout_chunks[1:, 0], executed[np.arange(4, 24, 4) - 1])
    with pytest.raises(ValueError, match="--actions deltas"):
        ChunkSampler(demos, obs_horizon=2, pred_horizon=16, representation="offsets")
    with pytest.raises(ValueError, match="cannot fill chunks of 32"):
        ChunkSampler(demos, obs_horizon=2, pred_horizon=32, representation="deltas")


def test_a_dagger_round_labels_only_from_the_overhang_asked_for(dart, trained, tmp_path):
    from agents.learned.dagger import DaggerConfig, run_dagger

    # the plate is still where it was put after 24 steps: no overhang, so nothing is asked
    config = DaggerConfig(
        rounds=1,
        episodes=1,
        iterations=2,
        max_steps=24,
        label_budget=60.0,
        chunk_every=4,
        label_from_overhang=0.01,
    )
    summary = run_dagger(trained, tmp_path / "dagger", "test/dagger-gate-v0", config, workers=1)
    (row,) = summary["rounds"]
    assert row["labelled_steps"] == 24
    assert row["label_queries"] == 0 and row["chunk_queries"] == 0
    aggregate = load("test/dagger-gate-v0")
    rollout = list(read_episodes(aggregate))[2]
    assert np.isnan(rollout.infos[LABEL_KEY][1:]).all()
    assert float(np.max(rollout.infos["overhang_m"])) < 0.01
    demos = load_demonstrations(aggregate)
    sampler = ChunkSampler(demos, obs_horizon=2, pred_horizon=16, representation="deltas")
    assert len(sampler) == int(demos.lengths[:2].sum())  # the rollout adds no window
    # from zero overhang on, every step is asked (the first chunk boundary takes over)
    config = dataclasses.replace(config, label_from_overhang=0.0)
    summary = run_dagger(trained, tmp_path / "open", "test/dagger-open-v0", config, workers=1)
    assert summary["rounds"][0]["label_queries"] >= 1
    assert summary["rounds"][0]["chunk_queries"] == 6


def test_states_the_demonstrations_do_not_reach_open_the_label_gate():
    import shapely

    from agents.learned.dagger import left_demonstrations

    plate = shapely.box(-0.05, -0.05, 0.05, 0.05)
    info = {"overhang_m": 0.02, "object_pose_2d": np.array([0.6, 0.1, np.pi / 4])}
    table = {"table_height": np.array([0.7])}

    def tip(x: float, y: float, z: float) -> dict[str, np.ndarray]:
        return {**table, "fingertip_pose": np.array([x, y, 0.7 + z, 0, 0, 0, 1.0])}

    on_plate, beside, above = tip(0.6, 0.1, 0.005), tip(0.6, 0.19, 0.005), tip(0.6, 0.19, 0.05)
    # turned 45 degrees, the square reaches 7.1 cm from its centre along y: 9 cm is off it
    assert not left_demonstrations(on_plate, info, plate, overhang=0.035, miss_height=0.015)
    assert left_demonstrations(beside, info, plate, overhang=0.035, miss_height=0.015)
    assert not left_demonstrations(above, info, plate, overhang=0.035, miss_height=0.015)
    assert not left_demonstrations(tip(0.6, 0.175, 0.005), info, plate, miss_height=0.015)
    assert not left_demonstrations(beside, info, plate, overhang=0.035)  # no miss gate
    slid = {**info, "overhang_m": 0.036}
    assert left_demonstrations(on_plate, slid, plate, overhang=0.035)
    assert not left_demonstrations(on_plate, slid, plate, miss_height=0.015)


def test_a_dagger_round_of_a_grasp_skill_keeps_its_slide_skill(
    dart, trained, tmp_path, monkeypatch
):
    import agents.learned.data as data
    from agents.learned.dagger import DaggerConfig, run_dagger
    from agents.learned.policy import FIRST_FILE, load_model, save_policy

    card = json.loads((trained / "policy.json").read_text())
    slide = load_model(trained / "policy.pt")
    save_policy(slide, tmp_path / "skills", {**card, "after": "s"}, first=slide)
    # the slide counts as done from step 10 of every episode (demonstrations and rollout)
    monkeypatch.setattr(data, "slide_done", lambda obs: np.arange(len(obs["arm_qpos"])) >= 10)
    config = DaggerConfig(rounds=1, episodes=1, iterations=4, max_steps=16, label_budget=60.0)
    summary = run_dagger(
        tmp_path / "skills", tmp_path / "d", "test/dagger-after-v0", config, workers=1
    )
    out = tmp_path / "d" / "round-1" / "policy"
    assert summary["policy"] == str(out)
    kept = load_model(out / FIRST_FILE)
    for name, value in slide.state_dict().items():  # the slide skill is not trained again
        torch.testing.assert_close(kept.state_dict()[name], value)
    policy_card = json.loads((out / "policy.json").read_text())
    assert policy_card["after"] == "s" and policy_card["demonstrations"]["after_slide"]
    lengths = [len(e.actions) for e in read_episodes(load("test/dagger-after-v0"))]
    assert lengths[-1] == 16  # the rollout is stored whole; training skips its first 10 steps
    assert policy_card["demonstrations"]["frames"] == sum(n - 10 for n in lengths)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["train-dp", "nobody/nothing-v0", "--out", "dp"], "no local dataset"),
        (["evaluate", "{empty}", "--episodes", "1"], "without a saved policy"),
        (["evaluate", "regions", "--episodes", "1", "--action-horizon", "4"], "action_horizon"),
        (["evaluate", "regions", "--episodes", "1", "--noise-scale", "0"], "noise_scale"),
        (["evaluate", "regions", "--episodes", "1", "--inference-steps", "5"], "inference_steps"),
        (["evaluate", "regions", "--episodes", "1", "--samples", "4"], "samples"),
        (
            ["collect", "--episodes", "1", "--action-noise", "-1", "--dataset-id", "t/x-v0"],
            "action_noise",
        ),
        (["collect", "--episodes", "1", "--dataset-id", "t/x.y-v0"], "NAMESPACE/NAME-vK"),
        (["dagger", "--policy", "{empty}", "--out", "d", "--dataset-id", "tt/d-v0"], "policy.pt"),
        (["train-dp", "nobody/nothing-v0", "--out", "dp", "--init", "{empty}"], "policy.pt"),
        (["choose-checkpoint", "{empty}"], "holds no snapshots"),
        (["train-dp", "nobody/nothing-v0", "--out", "dp", "--after", "{empty}"], "sliding policy"),
        (
            ["dagger", "--policy", "{empty}", "--skip-phases", "releese", "--out", "d"]
            + ["--dataset-id", "tt/d-v0"],
            "unknown expert phase(s) releese; allowed: plan, approach",
        ),
        (
            ["dagger", "--policy", "{empty}", "--chunk-labels", "-1", "--out", "d"]
            + ["--dataset-id", "tt/d-v0"],
            "--chunk-labels must be a whole number >= 0",
        ),
        (
            ["dagger", "--policy", "{empty}", "--label-from-overhang", "-0.01", "--out", "d"]
            + ["--dataset-id", "tt/d-v0"],
            "--label-from-overhang must be metres in [0, 1)",
        ),
        (
            ["dagger", "--policy", "{empty}", "--label-from-miss", "nan", "--out", "d"]
            + ["--dataset-id", "tt/d-v0"],
            "--label-from-miss must be metres in [0, 1)",
        ),
        (
            ["dagger", "--policy", "{empty}", "--expert-param", "straight_slide_on=2"]
            + ["--out", "d", "--dataset-id", "tt/d-v0"],
            "straight_slide_on must be True or False",
        ),
        (
            [
                "dagger",
                "--policy",
                "{empty}",
                "--rounds",
                "0",
                "--out",
                "d",
                "--dataset-id",
                "tt/d-v0",
            ],
            "--rounds",
        ),
    ],
)
def test_bad_input_is_one_line_and_exit_2(minari_root, tmp_path, args, needle, capsys):
    args = [a.replace("{empty}", str(tmp_path)) for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has a GPU")
def test_training_on_a_missing_gpu_is_one_line_and_exit_2(minari_root, capsys):
    assert main(["train-dp", "nobody/nothing-v0", "--out", "dp", "--device", "cuda"]) == 2
    err = capsys.readouterr().err
    assert "torch sees no GPU" in err and len(err.strip().splitlines()) == 1


def test_snapshots_are_validated_after_training_and_the_best_becomes_the_policy(
    dart, tmp_path, monkeypatch
):
    """A run without validation keeps its EMA weights every N iterations; choosing later
    validates each once (resumable), records the rates and copies the best (the later one
    on a tie) to the run's policy."""
    from agents.learned import train as train_module

    out = tmp_path / "run"
    train_diffusion(
        dart,
        out,
        config=TINY,
        train=_config(40),
        env_id=ENV_ID,
        env_kwargs={"object": "square", "table": "square"},
        progress=False,
        snapshot_every=20,
    )
    assert sorted(p.name for p in (out / "snapshots").iterdir()) == ["20", "40"]
    final = torch.load(out / "policy.pt", weights_only=False)["state_dict"]
    last = torch.load(out / "snapshots" / "40" / "policy.pt", weights_only=False)["state_dict"]
    for key in final:
        torch.testing.assert_close(final[key], last[key])
    rates = {20: 0.5, 40: 0.0}
    runs = []

    def fake_evaluate(policy, env_id, *, episodes, seed, env_kwargs, progress):
        iteration = policy.card["checkpoint"]["iteration"]
        runs.append(iteration)
        rate = rates[iteration]
        return {"success_rate": rate, "ci95": [0.0, 1.0], "episodes": episodes, "mean_length": 9}

    monkeypatch.setattr("agents.evaluate.evaluate", fake_evaluate)
    card = train_module.choose_snapshot(out, episodes=2)
    assert runs == [20, 40] and card["checkpoint"]["iteration"] == 20
    seed = train_module.VALIDATION_SEED
    assert card["checkpoint"]["seeds"] == [seed, seed + 1]
    chosen = torch.load(out / "policy.pt", weights_only=False)["state_dict"]
    first = torch.load(out / "snapshots" / "20" / "policy.pt", weights_only=False)["state_dict"]
    for key in chosen:
        torch.testing.assert_close(chosen[key], first[key])
    rows = {int(r["iteration"]): r for r in read_progress(out / "progress.csv")}
    assert float(rows[20]["val_success_rate"]) == 0.5 and rows[40]["val_episodes"] == "2"
    assert train_module.choose_snapshot(out, episodes=2)["checkpoint"]["iteration"] == 20
    assert runs == [20, 40]  # nothing ran again


def test_train_dp_defaults_are_the_configs():
    from slide_gym.cli import build_parser

    args = build_parser().parse_args(["train-dp", "some/data-v0", "--out", "run"])
    default = DiffusionConfig()
    assert tuple(args.channels) == default.channels
    assert (args.actions, args.scaling) == (default.actions, default.scaling)
    assert args.inference_steps == default.inference_steps
    assert args.no_features is not default.with_features


def test_slide_done_first_holds_at_the_lift_off_of_a_grasp_demonstration():
    """The expert's square-on-square grasp episode (seed 5, fingertip steps): slide_done is
    false through approach, press and slide, and first holds while the fingertip lifts off,
    long before the hand closes."""
    from agents.learned.features import slide_done
    from agents.planner_agent import PlannerAgent

    env = gym.make("SlideGym/TopSlideGrasp-v0", control_mode="ee_delta")
    agent = PlannerAgent(control_mode="ee_delta", seed=5)
    obs, _ = env.reset(seed=5)
    phases, done = [], []
    try:
        for _ in range(1200):
            action, _ = agent.predict(obs)
            phases.append(agent.expert(0).phase)
            done.append(bool(slide_done({k: v[None] for k, v in obs.items()})[0]))
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
    finally:
        agent.close()
        env.close()
    assert info["is_success"]
    first = done.index(True)
    assert phases[first] == "lift_off"
    assert not any(d for d, p in zip(done, phases, strict=True) if p in ("press", "slide"))
    assert first < phases.index("close") - 100


def test_after_slide_keeps_each_episode_from_its_finished_slide(dart, monkeypatch):
    import agents.learned.data as data

    full = load_demonstrations(dart)
    monkeypatch.setattr(data, "slide_done", lambda obs: np.arange(len(obs["arm_qpos"])) >= 30)
    later = load_demonstrations(dart, after_slide=True)
    np.testing.assert_array_equal(later.lengths, full.lengths - 30)
    first = full.labels[30 : full.lengths[0]]
    np.testing.assert_array_equal(later.labels[: later.lengths[0]], first)
    monkeypatch.setattr(data, "slide_done", lambda obs: np.zeros(len(obs["arm_qpos"]), bool))
    with pytest.raises(ValueError, match="no episode to learn from"):
        load_demonstrations(dart, after_slide=True)


def test_a_policy_after_a_slide_runs_the_first_skill_until_the_slide_is_done(
    trained, tmp_path, monkeypatch
):
    import agents.learned.policy as policy_module
    from agents.learned.policy import load_model, save_policy

    grasp, slide = load_model(trained / "policy.pt"), load_model(trained / "policy.pt")
    save_policy(grasp, tmp_path, {"env_id": ENV_ID}, first=slide)
    policy = DiffusionPolicy.load(tmp_path)
    assert len(policy.skills) == 2 and policy.skills[0] is not policy.model
    calls = []
    for name, skill in (("slide", policy.skills[0]), ("grasp", policy.model)):
        real = skill.sample
        monkeypatch.setattr(skill, "sample", lambda *a, n=name, r=real: calls.append(n) or r(*a))
    done = [False] * 3 + [True] * 10 + [False] * 2  # the switch is for the episode
    monkeypatch.setattr(policy_module, "slide_done", lambda obs: np.array([done.pop(0)]))
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    for t in range(14):
        policy.predict(obs, episode_start=np.array([t == 0]))
    # slide chunk at step 0; at step 3 the grasp skill starts with a fresh queue (8 steps),
    # and keeps acting when slide_done no longer holds
    assert calls == ["slide", "grasp", "grasp"]
    policy.predict(obs, episode_start=np.array([True]))
    assert calls[-1] == "slide"  # a new episode starts with the slide again


def test_fingertip_axes_stay_smooth_where_the_quaternion_flips_sign():
    from agents.learned.features import fingertip_axes, policy_input

    angles = np.linspace(2.9, 3.4, 11)  # a turn about z through pi: w crosses zero
    quat = np.column_stack([np.zeros((11, 2)), np.sin(angles / 2), np.cos(angles / 2)])
    quat[quat[:, 3] < 0] *= -1  # the sign convention w >= 0 makes the quaternion jump
    obs = {"fingertip_pose": np.column_stack([np.zeros((11, 3)), quat])}
    assert np.abs(np.diff(quat, axis=0)).max() > 1.0
    axes = fingertip_axes(obs)
    assert axes.shape == (11, 6)
    assert np.abs(np.diff(axes, axis=0)).max() < 0.1
    np.testing.assert_allclose(axes[:, 3:], np.tile([0.0, 0.0, 1.0], (11, 1)), atol=1e-6)
    env = gym.make(ENV_ID)
    real, _ = env.reset(seed=0)
    env.close()
    batch = {k: v[None] for k, v in real.items()}
    plain, more = policy_input(batch), policy_input(batch, tip_axes=True)
    assert more.shape[1] == plain.shape[1] + 6
    np.testing.assert_array_equal(more[:, :-6], plain)


def test_a_skill_with_tip_axes_may_follow_a_slide_skill_without(dart, trained, tmp_path):
    from dataclasses import replace

    from agents.learned.policy import load_model, save_policy

    train_diffusion(
        dart,
        tmp_path / "axes",
        config=replace(TINY, tip_axes=True),
        train=_config(2),
        env_id=ENV_ID,
        env_kwargs={"object": "square", "table": "square"},
        card={"dataset_id": DATASET},
        progress=False,
    )
    slide, grasp = load_model(trained / "policy.pt"), load_model(tmp_path / "axes" / "policy.pt")
    assert grasp.config.tip_axes and grasp.input_dim == slide.input_dim + 6
    save_policy(grasp, tmp_path / "both", {"env_id": ENV_ID}, first=slide)
    policy = DiffusionPolicy.load(tmp_path / "both")
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    env.close()
    action, _ = policy.predict(obs, episode_start=np.array([True]))
    assert action.shape == env.action_space.shape


def test_the_grasp_skill_benchmark_refuses_a_policy_without_a_slide_skill(
    trained, capsys, load_benchmark
):
    module = load_benchmark("grasp_skill")
    assert module.main([str(trained), "--episodes", "1"]) == 2
    assert "not a skill trained with --after" in capsys.readouterr().err
    assert module.main([str(trained), "--episodes", "0"]) == 2


def test_slide_failures_names_each_ending(trained, tmp_path, capsys, load_benchmark):
    module = load_benchmark("slide_failures")
    kind = module.failure_kind
    assert kind(True, 0.3, False, True) == "pushed off"
    assert kind(False, 0.001, False, True) == "never moved"
    assert kind(False, 0.2, True, True) == "graspable, still touched"
    assert kind(False, 0.2, False, False) == "short of u*"
    out = tmp_path / "failures.jsonl"
    assert module.main([str(trained), "--seeds", "20000-20000", "--out", str(out)]) == 0
    (summary,) = [json.loads(line) for line in out.read_text().splitlines()]
    (episode,) = summary["results"]
    assert summary["episodes"] == 1 and episode["seed"] == 20000
    assert episode["success"] or episode["kind"] in summary["failures"]
    assert summary["by_scene"] == {
        f"{episode['object']}/{episode['table']}": [int(episode["success"]), 1]
    }
    assert module.main([str(trained), "--seeds", "20000"]) == 2
    assert "--seeds FIRST-LAST" in capsys.readouterr().err


def test_slide_failures_names_each_grasp_ending(load_benchmark):
    kind = load_benchmark("slide_failures").grasp_failure_kind
    # fell_off, moved_m, ever_graspable, ever_pinched, most_lift_m, graspable now
    assert kind(True, 0.2, True, True, 0.05, False) == "dropped"
    assert kind(True, 0.2, True, False, 0.0, False) == "pushed off"
    assert kind(False, 0.001, False, False, 0.0, False) == "never moved"
    assert kind(False, 0.2, False, False, 0.0, False) == "short of u*"
    assert kind(False, 0.2, True, False, 0.0, True) == "graspable, never pinched"
    assert kind(False, 0.2, True, False, 0.0, False) == "pushed back"
    assert kind(False, 0.2, True, True, 0.005, True) == "pinched, not held"


def test_watch_grasp_prints_one_episode(trained, tmp_path, capsys, load_benchmark):
    main = load_benchmark("watch_grasp").main
    assert main([str(trained), "--seed", "20000", "--every", "50"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith(("success after", "failure after")) and last.endswith("steps")
    assert main([str(tmp_path / "missing")]) == 2
    assert "watch_grasp:" in capsys.readouterr().err


def test_slide_failures_names_a_dagger_round_by_its_row(load_benchmark, tmp_path):
    name = load_benchmark("slide_failures").policy_name
    assert name(tmp_path / "row" / "round-2" / "policy") == "row/round-2"
    assert name(tmp_path / "row") == "row"


def test_episode_seeds_keep_only_the_listed_episodes(dart, tmp_path, capsys):
    full = load_demonstrations(dart)
    only = load_demonstrations(dart, episode_seeds=frozenset({5}))
    assert full.seeds == [4, 5] and only.seeds == [5] and only.skipped == full.skipped + 1
    np.testing.assert_array_equal(only.labels, full.labels[full.starts[1] :])
    with pytest.raises(ValueError, match=r"1 of the 2 episode seeds are in no episode"):
        load_demonstrations(dart, episode_seeds=frozenset({5, 6}))
    seeds = tmp_path / "seeds.json"
    args = ["train-dp", DATASET, "--out", str(tmp_path / "run"), "--episode-seeds", str(seeds)]
    for text in ("[]", "[4, true]", "{", '"4"'):
        seeds.write_text(text)
        assert main(args) == 2
        err = capsys.readouterr().err
        assert "--episode-seeds" in err and len(err.strip().splitlines()) == 1
