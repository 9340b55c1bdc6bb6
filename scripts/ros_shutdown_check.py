#!/usr/bin/env python3
"""Starts launch/dem_nodelet.launch (nodelet manager + DemNodelet) on a master of its own, optionally
plays a bag into it, stops it with SIGINT as roslaunch does on Ctrl-C, and fails on an abnormal
exit: glibc heap errors ("double free or corruption", "free(): invalid pointer", ...), a crash
(segfault, abort, "terminate called"), a process that "has died" or a non-zero exit status.

    scripts/ros_shutdown_check.py [--bag FILE] [--frames-before-stop N] [--stop-while-processing] [--cycles K]

One line per cycle and a summary line; exit status 0 when every cycle ended cleanly. Needs a sourced
catkin workspace (source .catkin_ws/devel/setup.bash). Used by test/ros/shutdown.test."""
import argparse
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time

BAD = [
    r'double free', r'corruption', r'free\(\): invalid', r'munmap_chunk', r'malloc\(\)', r'Segmentation fault',
    r'Aborted', r'core dumped', r'terminate called', r'has died', r'stack smashing', r'pure virtual method called',
]


def free_port():
    s = socket.socket()
    s.bind(('127.0.0.1', 0))
    port = s.getsockname()[1]
    s.close()
    return port


def wait_for_service(master_uri, name, timeout):
    import rosgraph
    master = rosgraph.Master('/sgd_shutdown_check', master_uri=master_uri)
    end = time.time() + timeout
    while time.time() < end:
        try:
            master.lookupService(name)
            return True
        except Exception:  # master not up yet, or the service not advertised yet
            time.sleep(0.2)
    return False


def descendants(root):
    """PIDs of the processes below `root` (roslaunch gives each node a session of its own)."""
    children = {}
    for d in os.listdir('/proc'):
        if not d.isdigit():
            continue
        try:
            with open('/proc/%s/stat' % d) as f:
                ppid = int(f.read().rsplit(')', 1)[1].split()[1])  # after the name: state, ppid
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(d))
    out, todo = [], [root]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def loaders_ready(launch_pid, timeout):
    """Waits until every `nodelet load` process of the launch catches SIGINT. The loader installs
    its SIGINT handler (which unloads the nodelet from the manager) only after the manager's load
    call returned, i.e. after DemNodelet::onInit, which advertises the services early: a SIGINT in
    between kills the loader with the default action (exit -2), a race of this check, not a fault
    of the node. Linux: the handler shows as bit 1 of SigCgt in /proc/PID/status."""
    start = time.time()
    while time.time() < start + timeout:
        loaders = waiting = 0
        for pid in descendants(launch_pid):
            try:
                with open('/proc/%d/cmdline' % pid, 'rb') as f:
                    argv = f.read().split(b'\0')
                if b'load' not in argv or not any(a.endswith(b'nodelet') for a in argv):
                    continue
                with open('/proc/%d/status' % pid) as f:
                    sigcgt = int(re.search(r'SigCgt:\s*([0-9a-fA-F]+)', f.read()).group(1), 16)
                loaders += 1
                waiting += not (sigcgt >> (signal.SIGINT - 1)) & 1
            except (OSError, AttributeError, ValueError):
                continue  # gone or not readable: nothing to wait for
        if not waiting and (loaders or time.time() > start + 2.0):  # (none: a standalone nodelet)
            return True
        time.sleep(0.05)
    return False


def one_cycle(args, env, log_dir, k):
    # a master of its own per cycle: a master of the last cycle that is still going down would
    # otherwise answer for the new one, with the last cycle's service registrations
    env = dict(env, ROS_MASTER_URI='http://127.0.0.1:%d' % free_port())
    out_path = os.path.join(log_dir, 'launch_%d.txt' % k)
    with open(out_path, 'w') as out:
        launch = subprocess.Popen(
            ['roslaunch', '-p', env['ROS_MASTER_URI'].rsplit(':', 1)[1], 'stereo_ground_dem', 'dem_nodelet.launch',
             'lazy:=false', 'output:=screen'] + args.launch_args,
            stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    ready = wait_for_service(env['ROS_MASTER_URI'], '/stereo_ground_dem/reset', args.start_timeout)
    ready = ready and loaders_ready(launch.pid, args.start_timeout)
    played = 0
    if ready and args.bag:
        # a few frames at real rate, then stop (while the last one is processed with --stop-while-processing)
        duration = max(0.1, 0.1 * args.frames_before_stop)
        p = subprocess.run(['rosbag', 'play', '-q', '-u', '%.2f' % duration, args.bag], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        played = p.returncode == 0
        if not args.stop_while_processing:
            time.sleep(3.0)  # let the last frames finish
    launch.send_signal(signal.SIGINT)  # what roslaunch's Ctrl-C handler sends to the whole launch
    try:
        status = launch.wait(timeout=args.stop_timeout)
    except subprocess.TimeoutExpired:
        os.killpg(launch.pid, signal.SIGKILL)
        status = 'timeout'
    with open(out_path, errors='replace') as f:
        text = f.read()
    # roslaunch's own log has each node's exit status ("process[NAME-N]: SIGINT killed with return value R")
    import glob
    launch_log = ''
    for log in glob.glob(os.path.join(env['ROS_HOME'], 'log', '*', 'roslaunch-*-%d.log' % launch.pid)):
        with open(log, errors='replace') as f:
            launch_log += f.read()
    text += launch_log
    returns = [(name, int(r)) for name, r in re.findall(
        r'process\[([^\]]+)\]: SIGINT killed with return value (-?\d+)', launch_log)]
    bad_returns = ['%s returned %d' % (n, r) for n, r in returns if r != 0]
    found = [b for b in BAD if re.search(b, text)] + bad_returns
    # roslaunch reports each node's end: "process[NAME-N]: SIGINT killed with return value R" (log) or
    # "[NAME-N] escalating to SIGTERM" when a node does not end within 15 s
    escalated = 'escalating to SIG' in text
    ok = ready and status == 0 and not found and not escalated and (played or not args.bag) and len(returns) >= 2
    print('cycle %d: %s (started %s, bag %s, roslaunch exit %s, node exits %s%s%s) log %s' % (
        k, 'ok' if ok else 'FAILED', 'yes' if ready else 'NO', 'played' if played else ('-' if not args.bag else 'FAILED'),
        status, ' '.join('%s=%d' % r for r in returns) or 'unknown', ', found: ' + ', '.join(found) if found else '', ', a node had to be killed' if escalated else '',
        out_path))
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--bag', help='bag to play before stopping (kitti_to_bag output)')
    ap.add_argument('--frames-before-stop', type=int, default=3, help='bag seconds * 10 played before the stop')
    ap.add_argument('--stop-while-processing', action='store_true', help='SIGINT right after the last frame')
    ap.add_argument('--cycles', type=int, default=1)
    ap.add_argument('--start-timeout', type=float, default=60.0)
    ap.add_argument('--stop-timeout', type=float, default=40.0)
    ap.add_argument('--log-dir', default=None)
    ap.add_argument('launch_args', nargs='*', help='extra NAME:=VALUE arguments of dem_nodelet.launch')
    args = ap.parse_args()
    env = dict(os.environ)
    env['ROSCONSOLE_STDOUT_LINE_BUFFERED'] = '1'
    env['ROS_HOME'] = args.log_dir or tempfile.mkdtemp(prefix='sgd_shutdown_')
    log_dir = env['ROS_HOME']
    os.makedirs(log_dir, exist_ok=True)
    results = [one_cycle(args, env, log_dir, k) for k in range(args.cycles)]
    print('shutdown check: %d of %d start/stop cycles clean%s' % (
        sum(results), len(results), '' if all(results) else ' (FAILED)'))
    return 0 if all(results) else 1


if __name__ == '__main__':
    sys.exit(main())
