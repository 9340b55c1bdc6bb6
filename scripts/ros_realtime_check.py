#!/usr/bin/env python3
"""Does the nodelet keep up with a camera? Plays a bag (kitti_to_bag output) at its real rate with
`rosbag play` into launch/dem_nodelet.launch (on a master of its own) and prints one summary line:

  frames received (synchronized by the node), mapped (initialized, tracked or recovered), dropped (a
  newer frame arrived while the node was busy), skipped (invalid), failed (not fused); latency from
  the left image's arrival to the DEM's arrival, both seen by this script (= image stamp -> DEM
  publication for a live camera, plus transport), median and 95th percentile; odometry end-point
  drift against the sequence's poses.txt (base_link positions, from the first to the last mapped
  frame, over the true path length).

    source .catkin_ws/devel/setup.bash
    rosrun stereo_ground_dem kitti_to_bag --sequence ../shared/data/kitti_raw_0926_d0013_f000-079 \\
        --out /tmp/raw13.bag --static-tf
    scripts/ros_realtime_check.py --bag /tmp/raw13.bag --sequence ../shared/data/kitti_raw_0926_d0013_f000-079

Exit status 0 when the node mapped at least one frame. --json FILE also writes the figures."""
import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np


def free_port():
    s = socket.socket()
    s.bind(('127.0.0.1', 0))
    port = s.getsockname()[1]
    s.close()
    return port


def private_master(log_dir=None, prefix='sgd_realtime_'):
    """Points this process (and its children) at a master of its own on a free port, with its logs in
    log_dir (a new temporary folder if None): ROS_MASTER_URI and ROS_HOME. Call before importing rospy.
    Returns the port (start_node starts the master there)."""
    port = free_port()
    os.environ['ROS_MASTER_URI'] = 'http://127.0.0.1:%d' % port
    os.environ['ROS_HOME'] = log_dir or tempfile.mkdtemp(prefix=prefix)
    os.makedirs(os.environ['ROS_HOME'], exist_ok=True)
    return port


def start_node(port, stereo_ns, launch_args, log_path, timeout_s=60.0):
    """roslaunch dem_nodelet.launch (master on port, output:=log, its console into log_path) and wait
    until the nodelet's ~reset service is up (at most timeout_s). Returns the roslaunch process."""
    import rosgraph
    with open(log_path, 'w') as out:
        launch = subprocess.Popen(['roslaunch', '-p', str(port), 'stereo_ground_dem', 'dem_nodelet.launch',
                                   'stereo_ns:=' + stereo_ns, 'output:=log'] + list(launch_args),
                                  stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        master = rosgraph.Master('/sgd_realtime_check')
        end = time.time() + timeout_s
        while time.time() < end:
            try:
                master.lookupService('/stereo_ground_dem/reset')
                break
            except Exception:  # not up yet
                time.sleep(0.2)
    except BaseException:
        stop_node(launch)
        raise
    return launch


def stop_node(launch, timeout_s=40.0):
    """SIGINT to roslaunch (as Ctrl-C), SIGKILL to its process group if it has not ended in timeout_s."""
    launch.send_signal(signal.SIGINT)
    try:
        launch.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(launch.pid, signal.SIGKILL)


def diagnostic_count(diag, key):
    """An integer value of the node's diagnostics (dict key -> string); -1 if absent or not a number."""
    try:
        return int(diag.get(key, 'nan'))
    except ValueError:
        return -1


def read_poses(path):
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
    x, y, z, w = p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w
    t = np.eye(4)
    t[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    t[:3, 3] = [p.position.x, p.position.y, p.position.z]
    return t


def transform_to_matrix(tr):
    class P(object):
        pass
    p = P()
    p.orientation, p.position = tr.rotation, tr.translation
    return pose_to_matrix(p)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--bag', required=True)
    ap.add_argument('--sequence', help='the folder the bag was made from (poses.txt: drift)')
    ap.add_argument('--rate', type=float, default=1.0, help='rosbag play rate (1: real time)')
    ap.add_argument('--stereo-ns', default='/stereo')
    ap.add_argument('--json', help='also write the figures to this file')
    ap.add_argument('--log-dir', default=None)
    ap.add_argument('--verbose', action='store_true', help='per-frame positions')
    ap.add_argument('launch_args', nargs='*', help='extra NAME:=VALUE arguments of dem_nodelet.launch')
    args = ap.parse_args()

    # a master of our own, before rospy is imported
    port = private_master(args.log_dir)
    import rosbag
    import rospy
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Image
    from stereo_ground_dem.msg import HeightGrid

    # frame index of each left image stamp, and the camera mount, from the bag
    stamps, base_T_camera, bag_rate_hz = [], None, float('nan')
    with rosbag.Bag(args.bag) as bag:
        for topic, msg, _ in bag.read_messages(topics=[args.stereo_ns + '/left/image_rect', '/tf_static']):
            if topic == '/tf_static':
                for t in msg.transforms:
                    base_T_camera = transform_to_matrix(t.transform)
            else:
                stamps.append(round(msg.header.stamp.to_sec(), 6))
    if len(stamps) > 1:
        bag_rate_hz = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    index_of = {s: k for k, s in enumerate(stamps)}

    log_path = os.path.join(os.environ['ROS_HOME'], 'launch.txt')
    launch = start_node(port, args.stereo_ns, args.launch_args, log_path)
    try:
        rospy.init_node('sgd_realtime_check', disable_signals=True)
        lock = threading.Lock()
        image_wall, dem_wall, odoms, diag = {}, {}, {}, {}

        def on_image(m):
            with lock:
                image_wall.setdefault(round(m.header.stamp.to_sec(), 6), time.time())

        def on_dem(m):
            with lock:
                dem_wall[round(m.info.header.stamp.to_sec(), 6)] = time.time()

        def on_odom(m):
            with lock:
                odoms[round(m.header.stamp.to_sec(), 6)] = pose_to_matrix(m.pose.pose)

        def on_diag(m):
            for s in m.status:
                if 'stereo_ground_dem' in s.name:
                    with lock:
                        diag.clear()
                        diag.update({v.key: v.value for v in s.values})

        subs = [rospy.Subscriber(args.stereo_ns + '/left/image_rect', Image, on_image, queue_size=50,
                                 buff_size=2 ** 24),
                rospy.Subscriber('/stereo_ground_dem/dem', HeightGrid, on_dem, queue_size=50, buff_size=2 ** 26),
                rospy.Subscriber('/stereo_ground_dem/odom', Odometry, on_odom, queue_size=50),
                rospy.Subscriber('/diagnostics', DiagnosticArray, on_diag, queue_size=50)]
        time.sleep(2.0)  # subscriptions reach the node (lazy: it subscribes to the cameras now)
        play = subprocess.run(['rosbag', 'play', '-q', '-d', '1', '-r', str(args.rate), args.bag],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        # the last frame, then two diagnostics periods
        time.sleep(3.0)
        for s in subs:
            s.unregister()
    finally:
        stop_node(launch)
    if play.returncode != 0:
        print('realtime check: rosbag play failed:\n' + play.stdout)
        return 2

    def count(key):
        return diagnostic_count(diag, key)
    received = count('synchronized frames')
    mapped = count('initialized') + count('tracked') + count('recovered')
    dropped = count('dropped (busy: replaced by a newer frame)')
    skipped = count('skipped (invalid input)')
    failed = count('failed (pose predicted, map unchanged)')
    lat = [(dem_wall[s] - image_wall[s]) * 1e3 for s in dem_wall if s in image_wall]
    lat_median = float(np.median(lat)) if lat else float('nan')
    lat_95 = float(np.percentile(lat, 95)) if lat else float('nan')

    drift_m = path_m = float('nan')
    if args.sequence and odoms and base_T_camera is not None:
        truth = read_poses(os.path.join(args.sequence, 'poses.txt'))
        done = sorted(s for s in odoms if s in index_of)
        if len(done) >= 2:
            k0, k1 = index_of[done[0]], index_of[done[-1]]
            est = np.linalg.inv(odoms[done[0]]).dot(odoms[done[-1]])  # base_link k1 in base_link k0
            b, bi = base_T_camera, np.linalg.inv(base_T_camera)
            tru = b.dot(np.linalg.inv(truth[k0]).dot(truth[k1])).dot(bi)
            drift_m = float(np.linalg.norm(est[:3, 3] - tru[:3, 3]))
            if args.verbose:
                for s in done:
                    e = np.linalg.inv(odoms[done[0]]).dot(odoms[s])
                    t = b.dot(np.linalg.inv(truth[k0]).dot(truth[index_of[s]])).dot(bi)
                    print('frame %d: base_link estimated %s, true %s' % (
                        index_of[s], np.round(e[:3, 3], 3), np.round(t[:3, 3], 3)))
            path_m = float(sum(np.linalg.norm(truth[k][:3, 3] - truth[k - 1][:3, 3]) for k in range(k0 + 1, k1 + 1)))
    figures = dict(bag=os.path.basename(args.bag), frames_in_bag=len(stamps), bag_rate_hz=bag_rate_hz,
                   play_rate=args.rate, received=received, mapped=mapped, dropped=dropped, skipped=skipped,
                   failed=failed, dems=len(dem_wall), latency_median_ms=lat_median, latency_p95_ms=lat_95,
                   drift_m=drift_m, path_m=path_m,
                   drift_percent=100.0 * drift_m / path_m if path_m > 0 else float('nan'),
                   processing_mean_ms=diag.get('processing mean [ms]'), log=log_path)
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(figures, f, indent=1)
    print('realtime check: %s (%d frames, %.1f Hz x %.2f): received %d, mapped %d, dropped %d, skipped %d, '
          'failed %d; latency image -> DEM median %.0f ms, 95th %.0f ms; drift %.2f m over %.1f m (%.2f %%)' % (
              figures['bag'], len(stamps), bag_rate_hz, args.rate, received, mapped, dropped, skipped, failed,
              lat_median, lat_95, drift_m, path_m, figures['drift_percent']))
    return 0 if mapped > 0 else 1


if __name__ == '__main__':
    sys.exit(main())
