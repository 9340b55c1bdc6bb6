"""Shared helpers of the stereo_ground_dem rostests (test/ros/*.py).

Bags are made at test time (never committed): kitti_to_bag on data/kitti_seq06_sample or on a
sequence rendered by sgd_render. BagPlayer replays a bag frame by frame at a fixed wall-clock period
(slower than the camera: the estimator needs ~0.3 s per full-resolution KITTI frame on 2 cores), with
the bag's stamps (so the estimator sees the real frame timing), and records the wall time at which each
frame was published: latency = DEM arrival wall time - publication wall time of its images, i.e. the
latency from image arrival to DEM for a live camera whose stamps are its publication times.
"""
import math
import os
import subprocess
import tempfile
import threading
import time

import numpy as np
import rosbag
import rospy
import roslib.packages
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import OccupancyGrid, Odometry
from stereo_ground_dem.msg import GroundAttitude, HeightGrid

PKG = 'stereo_ground_dem'


def executable(name):
    found = roslib.packages.find_node(PKG, name)
    if not found:
        raise RuntimeError('cannot find the %s executable of %s (built?)' % (name, PKG))
    return found[0]


def source_dir():
    return roslib.packages.get_pkg_dir(PKG)


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    if p.returncode != 0:
        raise RuntimeError('%s failed (%d):\n%s' % (' '.join(cmd), p.returncode, p.stdout))
    return p.stdout


def make_bag(sequence_dir, out_bag, extra=()):
    run([executable('kitti_to_bag'), '--sequence', sequence_dir, '--out', out_bag, '--clock-hz', '0',
         '--static-tf'] + list(extra))
    return out_bag


def render(out_dir, frames, extra=()):
    run([executable('sgd_render'), '--scene', 'flat', '--frames', str(frames), '--out', out_dir, '--quiet',
         '--no-truth-maps'] + list(extra))
    return out_dir


def temp_dir():
    return tempfile.mkdtemp(prefix='sgd_rostest_')


def read_poses(path):
    """KITTI poses.txt -> list of 4x4 arrays (camera0_T_cameraK)."""
    out = []
    with open(path) as f:
        for line in f:
            v = [float(x) for x in line.split()]
            if len(v) == 12:
                t = np.eye(4)
                t[:3, :4] = np.array(v).reshape(3, 4)
                out.append(t)
    return out


def pose_to_matrix(p):
    q = p.orientation
    x, y, z, w = q.x, q.y, q.z, q.w
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = [p.position.x, p.position.y, p.position.z]
    return t


# base_link -> optical camera frame as kitti_to_bag --static-tf writes it (camera 1.65 m up).
def base_T_camera(height=1.65):
    t = np.eye(4)
    t[:3, :3] = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    t[2, 3] = height
    return t


def layer(msg, name):
    """A HeightGrid layer as a (cells along x, cells along y) array, grid_map index (i, j)."""
    k = list(msg.layers).index(name)
    nx = int(round(msg.info.length_x / msg.info.resolution))
    ny = int(round(msg.info.length_y / msg.info.resolution))
    return np.array(msg.data[k].data, dtype=np.float32).reshape(ny, nx).T  # column-major storage


def cell_centres(msg):
    """x[i], y[j] of the grid_map cells (index (0, 0) at the largest x and y)."""
    info = msg.info
    nx = int(round(info.length_x / info.resolution))
    ny = int(round(info.length_y / info.resolution))
    x = info.pose.position.x + info.length_x / 2 - info.resolution / 2 - np.arange(nx) * info.resolution
    y = info.pose.position.y + info.length_y / 2 - info.resolution / 2 - np.arange(ny) * info.resolution
    return x, y


class Recorder(object):
    """Subscribes to the node's outputs and /diagnostics and keeps what arrives (with wall times)."""

    def __init__(self, ns='/stereo_ground_dem'):
        self.lock = threading.Lock()
        self.dems, self.odoms, self.occupancy, self.diagnostics, self.attitudes = [], [], [], [], []
        self.subs = [
            rospy.Subscriber(ns + '/dem', HeightGrid, self._cb, callback_args=self.dems, queue_size=50,
                             buff_size=2 ** 26),
            rospy.Subscriber(ns + '/odom', Odometry, self._cb, callback_args=self.odoms, queue_size=50),
            rospy.Subscriber(ns + '/traversability', OccupancyGrid, self._cb, callback_args=self.occupancy,
                             queue_size=50, buff_size=2 ** 24),
            rospy.Subscriber('/diagnostics', DiagnosticArray, self._cb, callback_args=self.diagnostics,
                             queue_size=200),
            rospy.Subscriber(ns + '/ground_attitude', GroundAttitude, self._cb, callback_args=self.attitudes,
                             queue_size=50),
        ]

    def _cb(self, msg, store):
        with self.lock:
            store.append((time.time(), msg))

    def wait_connected(self, timeout=30.0):
        """Until the node subscribes to its cameras (lazy: after our subscription reached it)."""
        end = time.time() + timeout
        while time.time() < end and not rospy.is_shutdown():
            if all(s.get_num_connections() > 0 for s in self.subs[:3]):
                return True
            time.sleep(0.1)
        return False

    def diagnostic_statuses(self, name_part='stereo_ground_dem'):
        with self.lock:
            return [(t, s) for t, a in self.diagnostics for s in a.status if name_part in s.name]


class BagPlayer(object):
    """Publishes a bag's frames (the messages recorded at one bag time together) every `period_s`
    seconds of wall time per 0.1 s of bag time (gaps stay gaps), with their own header stamps (which
    kitti_to_bag's defect options may make differ from the bag time); /tf_static once, latched.
    `published`: (frame index, left image header stamp, wall time) per frame."""

    def __init__(self, bag_path):
        self.frames = []  # (bag time, header stamp of the first message, [(topic, msg)])
        self.static_tf = None
        pubs = {}
        with rosbag.Bag(bag_path) as bag:
            for topic, msg, t in bag.read_messages():
                if topic == '/clock':
                    continue
                if topic == '/tf_static':
                    self.static_tf = msg
                    continue
                t = t.to_sec()
                if not self.frames or abs(self.frames[-1][0] - t) > 1e-6:
                    self.frames.append((t, msg.header.stamp.to_sec(), []))
                self.frames[-1][2].append((topic, msg))
                if topic not in pubs:
                    pubs[topic] = rospy.Publisher(topic, type(msg), queue_size=10)
        self.pubs = pubs
        self.tf_pub = rospy.Publisher('/tf_static', type(self.static_tf), queue_size=1, latch=True) \
            if self.static_tf is not None else None
        self.published = []  # (frame index, stamp used, wall time)

    def wait_subscribed(self, timeout=30.0):
        end = time.time() + timeout
        while time.time() < end:
            if all(p.get_num_connections() > 0 for p in self.pubs.values()):
                return True
            time.sleep(0.1)
        return False

    def play(self, period_s):
        if self.tf_pub is not None:
            now = rospy.Time.now()
            for t in self.static_tf.transforms:
                t.header.stamp = now
            self.tf_pub.publish(self.static_tf)
        t0 = time.time() + 0.5
        b0 = self.frames[0][0]
        for k, (bag_time, stamp, msgs) in enumerate(self.frames):
            # the bag's spacing is kept (gaps stay gaps): period_s of wall time per 0.1 s of bag time
            target = t0 + (bag_time - b0) / 0.1 * period_s
            delay = target - time.time()
            if delay > 0:
                time.sleep(delay)
            wall = time.time()
            for topic, msg in msgs:
                self.pubs[topic].publish(msg)
            self.published.append((k, stamp, wall))
        time.sleep(period_s)


def play_bag(ns, bag_path, period_s):
    """Subscribes to the node's outputs under `ns`, waits until the node listens to the cameras,
    plays the bag (BagPlayer.play) and returns (Recorder, BagPlayer) with everything received."""
    rec = Recorder(ns)
    player = BagPlayer(bag_path)
    assert rec.wait_connected(), 'the node never connected to the test subscribers'
    assert player.wait_subscribed(), 'the node never subscribed to the cameras (lazy?)'
    player.play(period_s)
    time.sleep(1.0)
    return rec, player


def finite_known(a):
    """No infinities; returns the finite values."""
    if np.isinf(a).any():
        raise AssertionError('infinite values in a published layer')
    return a[np.isfinite(a)]


def percentile(values, q):
    return float(np.percentile(np.asarray(values), q)) if len(values) else float('nan')
