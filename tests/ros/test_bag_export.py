"""`foldbot export-bag` without ROS: an episode folder becomes a ROS 1 bag (rosbags), whose
messages read back as the episode's frames, camera, ground truth and result."""

import json
import subprocess
import sys

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from foldbot.io.episode import load_episode


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "episode"
    # 8 vertices along a side: at 6 or 7 this towel's fold slides away (0.67 m/s) and is a
    # divergence, which writes no episode to export.
    subprocess.run(
        [
            sys.executable,
            "-m",
            "foldbot.cli",
            "fold",
            "--resolution",
            "8",
            "--video-fps",
            "2",
            "--out",
            str(out),
        ],
        check=True,
        capture_output=True,
        timeout=600,
    )
    return out


@pytest.mark.slow
def test_export_reads_back(episode, tmp_path):
    from foldbot.ros.bag_export import export_episode

    bag = tmp_path / "episode.bag"
    counts = export_episode(episode, bag)
    result = json.loads((episode / "result.json").read_text())
    cloth = load_episode(episode)
    assert counts["/camera/color/image_raw"] == counts["/camera/color/camera_info"] > 5
    with AnyReader([bag]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types["/camera/color/image_raw"] == "sensor_msgs/msg/Image"
        assert types["/tf_static"] == "tf2_msgs/msg/TFMessage"
        msgs = {}
        for conn, _t, raw in reader.messages():
            msgs.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    img = msgs["/camera/color/image_raw"][0]
    assert (img.encoding, img.width, img.height) == ("rgb8", 640, 480)
    np.testing.assert_allclose(
        np.reshape(msgs["/camera/color/camera_info"][0].K, (3, 3)), result["camera"]["K"]
    )
    initial = np.frombuffer(
        msgs["/ground_truth/cloth_initial"][0].data.tobytes(), np.float32
    ).reshape(-1, 3)
    np.testing.assert_allclose(initial, cloth.initial, atol=1e-6)
    assert json.loads(msgs["/task/result"][0].data)["fold_error_mm"] == result["fold_error_mm"]
    assert len(msgs["/fold/grasp_points"][0].poses) == len(result["actions"])


def test_refuses_to_overwrite(episode, tmp_path):
    from foldbot.errors import OutputError
    from foldbot.ros.bag_export import export_episode

    bag = tmp_path / "x.bag"
    bag.write_bytes(b"keep")
    with pytest.raises(OutputError, match="already exists"):
        export_episode(episode, bag)
    assert bag.read_bytes() == b"keep"


def test_a_cloth_score_would_refuse_is_refused_and_no_partial_bag_is_left(tmp_path):
    from foldbot.errors import ConfigError, OutputError
    from foldbot.io.episode import REQUIRED_RESULT_KEYS, EpisodeWriter
    from foldbot.ros.bag_export import export_episode

    xs = np.linspace(0.0, 0.3, 3)
    initial = np.array([[x, y, 0.76] for y in xs for x in xs])
    faces = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    result = {**dict.fromkeys(REQUIRED_RESULT_KEYS, 0), "fold_lines": [[0.15, 0, 0, 1]]}
    with EpisodeWriter(tmp_path / "ep") as w:
        w.write_cloth(faces, initial, initial, 0.002)
        w.write_result({**result, "actions": []})
    bags = tmp_path / "bags"
    assert export_episode(tmp_path / "ep", bags / "ok.bag")["/task/result"] == 1
    for bad in (np.nan, np.inf, 1e300):
        final = initial.copy()
        final[4] = bad
        np.savez(tmp_path / "ep" / "cloth.npz", faces=faces, initial=initial, final=final,
                 thickness=0.002)  # fmt: skip
        with pytest.raises(ConfigError, match=r"cloth\.npz in .*: final has "):
            export_episode(tmp_path / "ep", bags / "ok.bag", overwrite=True)
    (bags / "d.bag").mkdir()
    with pytest.raises(OutputError, match=r"d\.bag is a folder; name a \.bag file"):
        export_episode(tmp_path / "ep", bags / "d.bag", overwrite=True)
    assert sorted(p.name for p in bags.iterdir()) == ["d.bag", "ok.bag"]  # no partial bag
