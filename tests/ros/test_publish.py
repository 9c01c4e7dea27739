"""publish_when_heard with a live roscore: a request published before its subscriber comes up
still reaches it (a plain publish is dropped), and no subscriber at all is an error naming the
topic."""

import subprocess
import sys
import textwrap
import time

import pytest
from ros_helpers import private_master, requires_ros

pytestmark = requires_ros

TALKER = textwrap.dedent(
    """
    import sys
    import rospy
    from std_msgs.msg import String
    from foldbot.errors import FoldbotError
    from foldbot.ros.publish import publish_when_heard

    rospy.init_node("talker", disable_signals=True)
    pub = rospy.Publisher("request", String, queue_size=5)
    try:
        publish_when_heard(pub, String(data="park"), timeout_s=float(sys.argv[1]))
    except FoldbotError as exc:
        print("error:", exc, flush=True)
        sys.exit(3)
    rospy.sleep(1.0)  # let the message leave before the node goes
    print("sent", flush=True)
    """
)
LISTENER = textwrap.dedent(
    """
    import rospy
    from std_msgs.msg import String

    rospy.init_node("listener", disable_signals=True)
    got = []
    rospy.Subscriber("request", String, lambda m: got.append(m.data))
    deadline = rospy.Time.now().to_sec() + 30.0
    while not got and rospy.Time.now().to_sec() < deadline:
        rospy.sleep(0.05)
    print("got", got[0] if got else None, flush=True)
    """
)


@pytest.fixture()
def master():
    """A private roscore; yields the environment that reaches it."""
    with private_master() as env:
        yield env


def python(code: str, *args: str, env: dict) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", code, *args], env=env, stdout=subprocess.PIPE, text=True
    )


def test_a_request_waits_for_a_late_subscriber(master):
    talker = python(TALKER, "60", env=master)
    time.sleep(3.0)  # the talker has published by now, were it not waiting
    listener = python(LISTENER, env=master)
    heard, _ = listener.communicate(timeout=90)
    said, _ = talker.communicate(timeout=90)
    assert said.strip() == "sent"
    assert heard.strip() == "got park"


def test_no_subscriber_is_an_error_naming_the_topic(master):
    talker = python(TALKER, "0.5", env=master)
    said, _ = talker.communicate(timeout=90)
    assert talker.returncode == 3
    assert said.strip() == "error: nothing subscribed to /request within 0.5 s"


GATE = textwrap.dedent(
    """
    import rosgraph
    import rospy
    from std_msgs.msg import String
    from foldbot.ros.publish import wait_for_listed_subscribers

    rospy.init_node("gate", disable_signals=True)
    # Room for both reports below: published back to back, with a queue of one rospy drops the
    # first when the second comes before its writer thread has sent it (seen once in CI, on a
    # loaded machine). The sim node reports once per command sent to it, a round trip apart.
    pub = rospy.Publisher("request", String, queue_size=2, latch=True)
    print("missing", wait_for_listed_subscribers([pub], "reporting", timeout_s=60.0), flush=True)
    # The first report reaches the listener, though the next replaces it as the latched one at
    # once (as the sim node's ready report is replaced by its first command's).
    pub.publish(String(data="ready"))
    pub.publish(String(data="moved"))
    rospy.sleep(1.0)
    # A subscriber the master lists that never connects (a node gone without unregistering):
    # the wait ends at its timeout and names it.
    rosgraph.Master("/ghost").registerSubscriber("/request", "std_msgs/String", "http://localhost:9/")
    print("missing", wait_for_listed_subscribers([pub], "reporting", timeout_s=0.5), flush=True)
    """
)


def test_a_start_waits_for_the_listed_subscribers_to_connect(master):
    import rosgraph

    listener = python(LISTENER, env=master)
    deadline = time.monotonic() + 60
    while "/request" not in dict(
        rosgraph.Master("/t", master["ROS_MASTER_URI"]).getSystemState()[1]
    ):
        assert time.monotonic() < deadline, "the listener never subscribed"
        time.sleep(0.05)
    gate = python(GATE, env=master)
    said, _ = gate.communicate(timeout=90)
    heard, _ = listener.communicate(timeout=90)
    assert said.splitlines() == ["missing []", "missing ['/ghost on /request']"]
    assert heard.strip() == "got ready"
