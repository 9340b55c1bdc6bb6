#!/usr/bin/env python3
"""Soak test through ROS: does the nodelet run for thousands of frames with flat memory and no failed frame?

Renders a long synthetic drive with `sgd_render` (scene `flat` at full KITTI resolution, 1 m/frame,
10 Hz stamps, supersampling 1, no truth maps) and turns it into a bag with `kitti_to_bag
--static-tf`; both are cached (default /tmp/sgd_soak: the bag and the sequence's text files, the
PNGs are deleted once the bag is written) and reused by later runs. The number of rendered frames is
--frames unless the renderer, timed on 20 frames first, would need more than --render-budget-s: then
fewer are rendered and the bag is played in a loop. Then, on a master of its own (the helpers of
scripts/ros_realtime_check.py), it runs launch/dem_nodelet.launch, subscribes to every output of the
node (so every output is built and published) and plays the bag with `rosbag play -l` at --rate (0.3
of the bag's 10 Hz by default: the node needs 0.2-0.3 s per full-resolution frame on 2 cores; the
point is memory and failures, not speed) until the node has processed --frames frames.

Every --every processed frames (from the node's /diagnostics) it samples the nodelet manager's
resident memory (VmRSS and its peak VmHWM in /proc/PID/status) and prints a row: processed frames,
resident MB, peak MB, the map's own memory (diagnostics), failed frames, map resets, dropped and
skipped frames so far, elapsed time. A loop of the bag makes the stamps jump backwards, which the
node treats as a restart (a new map): those resets are counted separately and are not failures.
Frames dropped because the node was busy (a newer frame arrived) are not failures either.

At the end: frames mapped / failed / dropped / skipped, and the growth of the resident memory from
frame 200 (the map and every buffer have reached their working size by then: the map is bounded by
map_keep_radius_m, the path by path_max_poses) to the last sample, to the highest sample (the bound
applies to this one: a last sample just after a loop's reset, with a new small map, would hide a
growth) and of the peak (VmHWM); and the trend (least squares, KB per frame) over the samples of one
map from frame 200 on. Each "tracking failed" warning of the node is listed with its frame (the first
odometry published after the warning) and bag loop.

    source .catkin_ws/devel/setup.bash
    scripts/ros_soak.py --frames 200                 # smoke test, ~2 min (+ rendering on the first run)
    scripts/ros_soak.py --json /tmp/soak.json        # 2,000 frames, ~12 min (+ ~4-10 min rendering the
                                                     # first time; the bag is 1.8 GB)

Exit status 0 when the node processed --frames frames with no failed or skipped frame and the
highest resident sample from frame 200 on was at most --max-growth-percent (10 %) above the one at
frame 200 (measured over 2,000 frames on 2026-12-02, with the node's periodic release of free heap,
`~release_memory_every_frames`: the samples from frame 201 on spread over 146.1-152.8 MB, 4.6 %, as
the allocator keeps and returns memory; 10 % = 15 MB of ~150 MB is above that noise and still
catches a leak of 8 KB per frame over 1,800 frames; without the release the same run rose 12.6 %,
docs/results.md section 4); 1 otherwise;
2 when the sequence or the bag could not be made.
"""
import argparse
import fcntl
import glob
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ros_realtime_check as rt  # noqa: E402  (private master, start/stop of dem_nodelet.launch)

BAG_START_TIME = 1e9  # kitti_to_bag's default --start-time: stamp of frame 0
FAILED = 'failed (pose predicted, map unchanged)'
DROPPED = 'dropped (busy: replaced by a newer frame)'
SKIPPED = 'skipped (invalid input)'


def prefixes():
    return [p for p in os.environ.get('CMAKE_PREFIX_PATH', '').split(':') if p]


def tool(name):
    """A binary of the package from the sourced workspace (CMAKE_PREFIX_PATH, as rosrun finds it)."""
    for p in prefixes():
        path = os.path.join(p, 'lib', 'stereo_ground_dem', name)
        if os.access(path, os.X_OK):
            return path
    sys.exit('ros_soak: %s not found: source the workspace (source .catkin_ws/devel/setup.bash)' % name)


def package_libraries():
    """The package's shared libraries with their modification times (a rebuild during the soak shows)."""
    out = {}
    for p in prefixes():
        for path in sorted(glob.glob(os.path.join(p, 'lib', 'libstereo_ground_dem*.so'))):
            out.setdefault(os.path.basename(path), (path, os.path.getmtime(path)))
    return out


def git_state():
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        head = subprocess.run(['git', '-C', here, 'rev-parse', '--short', 'HEAD'], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, universal_newlines=True).stdout.strip()
        dirty = subprocess.run(['git', '-C', here, 'status', '--porcelain', '--untracked-files=no'],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               universal_newlines=True).stdout.split('\n')
        return head, sorted(line[3:] for line in dirty if line.strip())
    except OSError:
        return '', []


# ---------------------------------------------------------------- the synthetic sequence and its bag

def render(out_dir, frames, scene):
    if os.path.exists(out_dir):
        shutil.rmtree(out_dir)
    t0 = time.time()
    p = subprocess.run([tool('sgd_render'), '--scene', scene, '--frames', str(frames), '--out', out_dir,
                        '--supersampling', '1', '--no-truth-maps', '--quiet'],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    if p.returncode != 0:
        sys.stderr.write(p.stdout)
        raise RuntimeError('sgd_render failed (exit %d)' % p.returncode)
    return time.time() - t0


def cached_bags(cache, scene):
    """meta of every complete bag in the cache (written last, after the bag)."""
    out = []
    for path in glob.glob(os.path.join(cache, '%s_*f.json' % scene)):
        try:
            with open(path) as f:
                meta = json.load(f)
        except (OSError, ValueError):
            continue
        if os.path.isfile(meta.get('bag', '')) and os.path.getsize(meta['bag']) == meta.get('bag_bytes'):
            out.append(meta)
    return sorted(out, key=lambda m: m['frames'])


def make_bag(cache, scene, frames, budget_s):
    """The cached bag with at least `frames` frames, or a new one (fewer frames if rendering them would
    exceed budget_s). Returns its meta: bag, sequence (text files only), frames, render_s, bag_bytes.
    One run at a time renders into a cache (a lock file): a second run waits, then reuses the bag."""
    os.makedirs(cache, exist_ok=True)
    with open(os.path.join(cache, '.lock'), 'w') as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            print('soak: another run is making a bag in %s: waiting for it' % cache)
            sys.stdout.flush()
            fcntl.flock(lock, fcntl.LOCK_EX)
        return make_bag_locked(cache, scene, frames, budget_s)


def make_bag_locked(cache, scene, frames, budget_s):
    cached = cached_bags(cache, scene)
    enough = [m for m in cached if m['frames'] >= frames]
    if enough:
        return enough[0]
    probe_dir = os.path.join(cache, 'probe')
    probe_s = render(probe_dir, 20, scene)
    shutil.rmtree(probe_dir)
    per_frame = probe_s / 20.0
    n = frames
    if n * per_frame > budget_s:
        n = max(100, int(budget_s / per_frame) // 100 * 100)
    print('soak: sgd_render takes %.2f s per frame here (20-frame probe): %d frames would take %.0f s%s' % (
        per_frame, frames, frames * per_frame,
        '' if n == frames else ' > %.0f s budget: rendering %d and looping the bag' % (budget_s, n)))
    sys.stdout.flush()
    longer = [m for m in cached if m['frames'] >= n]
    if longer:
        return longer[-1]
    name = '%s_%df' % (scene, n)
    seq = os.path.join(cache, name)
    bag = seq + '.bag'
    print('soak: rendering %d frames of scene %s into %s ...' % (n, scene, seq))
    sys.stdout.flush()
    render_s = render(seq, n, scene)
    print('soak: rendered in %.0f s; writing %s ...' % (render_s, bag))
    sys.stdout.flush()
    partial = seq + '.partial.bag'
    t0 = time.time()
    p = subprocess.run([tool('kitti_to_bag'), '--sequence', seq, '--out', partial, '--static-tf'],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    if p.returncode != 0:
        sys.stderr.write(p.stdout)
        raise RuntimeError('kitti_to_bag failed (exit %d)' % p.returncode)
    os.rename(partial, bag)
    bag_s = time.time() - t0
    for sub in ('image_0', 'image_1'):  # the bag has them; keep the text files (times.txt, poses.txt)
        shutil.rmtree(os.path.join(seq, sub), ignore_errors=True)
    meta = dict(bag=bag, sequence=seq, scene=scene, frames=n, supersampling=1, render_s=render_s,
                render_s_per_frame=render_s / n, kitti_to_bag_s=bag_s, bag_bytes=os.path.getsize(bag),
                created=time.strftime('%Y-%m-%d %H:%M:%S'))
    with open(seq + '.json', 'w') as f:
        json.dump(meta, f, indent=1)
    return meta


def read_times(sequence):
    try:
        with open(os.path.join(sequence, 'times.txt')) as f:
            t = [float(line) for line in f if line.strip()]
        return [BAG_START_TIME + (x - t[0]) for x in t]
    except (OSError, ValueError, IndexError):
        return []


# ---------------------------------------------------------------- the soak

def memory_mb(pid):
    """VmRSS and VmHWM (peak) of a process [MB], NaN if it is gone."""
    out = {'VmRSS': float('nan'), 'VmHWM': float('nan')}
    try:
        with open('/proc/%d/status' % pid) as f:
            for line in f:
                key = line.split(':')[0]
                if key in out:
                    out[key] = int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return out['VmRSS'], out['VmHWM']


def node_pid(name, caller='/sgd_soak'):
    import rosgraph
    import xmlrpc.client
    end = time.time() + 30
    while True:
        try:
            uri = rosgraph.Master(caller).lookupNode(name)
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid(caller)
            if code == 1:
                return int(pid)
        except Exception:
            if time.time() > end:
                raise
        time.sleep(0.2)


def stop_play(play):
    if play.poll() is None:
        os.killpg(play.pid, signal.SIGINT)
        try:
            play.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(play.pid, signal.SIGKILL)
            play.wait()


def pattern(text):
    """A warning with its numbers replaced, to count warnings of the same kind."""
    return re.sub(r'-?\d+(\.\d+)?(e-?\d+)?', '#', text)


def soak(args, bag, times):
    launch_args = list(args.launch_args)
    manager = '/stereo_ground_dem_manager'
    for a in launch_args:
        if a.startswith('manager:='):
            manager = '/' + a.split(':=', 1)[1].lstrip('/')
    port = rt.private_master(args.log_dir, prefix='sgd_soak_')
    import rospy
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Log

    log_path = os.path.join(os.environ['ROS_HOME'], 'launch.txt')
    libraries_before = package_libraries()
    lock = threading.Lock()
    done = threading.Event()
    state = dict(diag={}, next_mark=args.every, rows=[], last_progress=time.time(), processed=0)
    odoms, warnings = [], []  # (arrival wall time, stamp); (log wall time, text)
    t_start = time.time()
    launch = rt.start_node(port, args.stereo_ns, launch_args, log_path)
    play = None
    play_log = os.path.join(os.environ['ROS_HOME'], 'rosbag_play.txt')
    try:
        pid = node_pid(manager)
        rss0, _ = memory_mb(pid)
        print('soak: nodelet manager %s pid %d, %.1f MB resident before the first frame; logs in %s' % (
            manager, pid, rss0, os.environ['ROS_HOME']))
        rospy.init_node('sgd_soak', disable_signals=True)

        def count(diag, key):
            return rt.diagnostic_count(diag, key)

        def sample(diag):
            rss, peak = memory_mb(pid)
            try:
                map_mb = float(diag.get('map memory [MB]', 'nan'))
            except ValueError:
                map_mb = float('nan')
            return dict(processed=count(diag, 'processed frames'), resident_mb=rss, peak_mb=peak, map_mb=map_mb,
                        map_tiles=count(diag, 'map tiles'), failed=count(diag, FAILED),
                        resets=count(diag, 'map restarts'), dropped=count(diag, DROPPED),
                        skipped=count(diag, SKIPPED), elapsed_s=time.time() - t_start)

        def on_diag(m):
            for s in m.status:
                if 'stereo_ground_dem' not in s.name:
                    continue
                diag = {v.key: v.value for v in s.values}
                with lock:
                    state['diag'] = diag
                    processed = count(diag, 'processed frames')
                    if processed > state['processed']:
                        state['processed'] = processed
                        state['last_progress'] = time.time()
                    if processed >= state['next_mark']:
                        state['rows'].append(sample(diag))
                        while state['next_mark'] <= processed:
                            state['next_mark'] += args.every
                    if processed >= args.frames:
                        done.set()

        def on_odom(m):
            with lock:
                odoms.append((time.time(), m.header.stamp.to_sec()))

        def on_log(m):
            if m.level >= Log.WARN and 'stereo_ground_dem' in m.name:
                with lock:
                    warnings.append((m.header.stamp.to_sec(), m.msg))

        node = '/stereo_ground_dem/'
        subs = [rospy.Subscriber(node + t, rospy.AnyMsg, lambda m: None, queue_size=5)
                for t in ('dem', 'dem_global', 'traversability', 'traversability_global', 'mesh', 'path')]
        subs += [rospy.Subscriber(node + 'odom', Odometry, on_odom, queue_size=50),
                 rospy.Subscriber('/diagnostics', DiagnosticArray, on_diag, queue_size=50),
                 rospy.Subscriber('/rosout', Log, on_log, queue_size=200)]
        time.sleep(2.0)  # subscriptions reach the node (lazy: it subscribes to the cameras now)
        with open(play_log, 'w') as out:
            play = subprocess.Popen(['rosbag', 'play', '-q', '-l', '-d', '1', '-r', str(args.rate), bag],
                                    stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        print('soak: playing %s in a loop at %.2fx until %d frames are processed' % (bag, args.rate, args.frames))
        print('%9s %12s %8s %7s %7s %7s %8s %8s %10s' % ('processed', 'resident MB', 'peak MB', 'map MB', 'failed',
                                                        'resets', 'dropped', 'skipped', 'elapsed s'))
        sys.stdout.flush()
        printed, stop_reason = 0, ''
        while True:
            finished = done.wait(0.5)
            with lock:
                rows = list(state['rows'])
                stalled = time.time() - state['last_progress']
            for r in rows[printed:]:
                print('%9d %12.1f %8.1f %7.2f %7d %7d %8d %8d %10.0f' % (
                    r['processed'], r['resident_mb'], r['peak_mb'], r['map_mb'], r['failed'], r['resets'],
                    r['dropped'], r['skipped'], r['elapsed_s']))
                sys.stdout.flush()
            printed = len(rows)
            if finished:
                break
            if launch.poll() is not None:
                stop_reason = 'the node (roslaunch) ended with %s' % launch.returncode
            elif play.poll() is not None:
                stop_reason = 'rosbag play ended with %s (%s)' % (play.returncode, play_log)
            elif stalled > args.stall_s:
                stop_reason = 'no frame processed for %.0f s' % stalled
            if stop_reason:
                print('soak: stopped early: ' + stop_reason)
                break
        stop_play(play)
        time.sleep(2.5)  # two diagnostics periods: the final counts
        with lock:
            final = sample(state['diag'])
        for s in subs:
            s.unregister()
    finally:
        if play is not None:
            stop_play(play)
        rt.stop_node(launch)
    wall_s = time.time() - t_start
    libraries_after = package_libraries()
    rebuilt = sorted(k for k, v in libraries_before.items() if libraries_after.get(k, (None, None))[1] != v[1])
    with lock:
        return dict(rows=list(state['rows']), final=final, diag=dict(state['diag']), odoms=list(odoms),
                    warnings=list(warnings), wall_s=wall_s, stop_reason=stop_reason, log_dir=os.environ['ROS_HOME'],
                    manager_pid=pid, resident_before_mb=rss0, rebuilt_during_run=rebuilt,
                    play_returncode=play.returncode if play is not None else None)


def memory_figures(rows, base_mark):
    """Resident memory from the first sample at or after base_mark to the last one, to the highest one
    (the bound applies to it) and of the peak (VmHWM); the least-squares trend over the samples of the
    same map (no reset since base_mark). NaN where there are too few samples."""
    nan = float('nan')
    m = dict(base=None, last=rows[-1] if rows else None, from_frame=None, to_frame=None, growth_mb=nan,
             growth_percent=nan, max_mb=nan, max_growth_mb=nan, max_growth_percent=nan, peak_growth_mb=nan,
             trend_kb_per_frame=nan, trend_frames=None, last_after_reset=False)
    base = next((r for r in rows if r['processed'] >= base_mark), None)
    if base is None:
        return m
    last = m['last']
    later = [r for r in rows if r['processed'] >= base['processed']]
    m.update(base=base, from_frame=base['processed'], to_frame=last['processed'],
             growth_mb=last['resident_mb'] - base['resident_mb'], max_mb=max(r['resident_mb'] for r in later),
             peak_growth_mb=last['peak_mb'] - base['peak_mb'], last_after_reset=last['resets'] != base['resets'])
    m['growth_percent'] = 100.0 * m['growth_mb'] / base['resident_mb']
    m['max_growth_mb'] = m['max_mb'] - base['resident_mb']
    m['max_growth_percent'] = 100.0 * m['max_growth_mb'] / base['resident_mb']
    one_map = [r for r in later if r['resets'] == base['resets']]
    if len(one_map) >= 3:
        m['trend_kb_per_frame'] = 1024.0 * float(np.polyfit([r['processed'] for r in one_map],
                                                             [r['resident_mb'] for r in one_map], 1)[0])
        m['trend_frames'] = [one_map[0]['processed'], one_map[-1]['processed']]
    return m


def memory_summary(m, bound_percent, before_mb):
    base, last = m['base'], m['last']
    if base is None:
        return ['too few memory samples for a growth figure']
    lines = ['resident memory %.1f MB at frame %d -> %.1f MB at frame %d: %+.1f MB (%+.1f %%)%s; highest from frame %d '
             'on %.1f MB: %+.1f MB (%+.1f %%, bound %.0f %%); peak (VmHWM) %.1f -> %.1f MB (%+.1f MB); %.1f MB before '
             'the first frame' % (
                 base['resident_mb'], base['processed'], last['resident_mb'], last['processed'], m['growth_mb'],
                 m['growth_percent'], ' (the last sample follows a map reset)' if m['last_after_reset'] else '',
                 base['processed'], m['max_mb'], m['max_growth_mb'], m['max_growth_percent'], bound_percent,
                 base['peak_mb'], last['peak_mb'], m['peak_growth_mb'], before_mb)]
    if m['trend_frames']:
        a, b = m['trend_frames']
        lines.append('resident memory trend %+.1f KB/frame (least squares over the samples of one map, frames %d-%d: '
                     '%+.1f MB over them)' % (m['trend_kb_per_frame'], a, b, m['trend_kb_per_frame'] * (b - a) / 1024.0))
    return lines


def locate_failures(result, times):
    """Each 'tracking failed' warning -> the frame of the first odometry that arrived after it (the
    worker logs the failure just before it publishes that frame) and the loop of the bag it was in."""
    odoms = result['odoms']
    loop_of, loop = [], 0
    for k, (_, stamp) in enumerate(odoms):
        if k > 0 and stamp < odoms[k - 1][1]:
            loop += 1
        loop_of.append(loop)
    out = []
    for t_log, text in result['warnings']:
        if 'tracking failed' not in text:
            continue
        k = next((i for i, (arrival, _) in enumerate(odoms) if arrival >= t_log), None)
        entry = dict(message=text, log_time=t_log)
        if k is not None:
            stamp = odoms[k][1]
            entry.update(stamp=stamp, loop=loop_of[k], published_index=k)
            if times:
                frame = min(range(len(times)), key=lambda i: abs(times[i] - stamp))
                if abs(times[frame] - stamp) < 1e-3:
                    entry['frame'] = frame
        out.append(entry)
    return out, loop


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--frames', type=int, default=2000, help='frames the node must process (default 2000)')
    ap.add_argument('--rate', type=float, default=0.3, help='rosbag play rate (default 0.3: 3 Hz of a 10 Hz bag)')
    ap.add_argument('--every', type=int, default=100, help='memory sample every N processed frames (100)')
    ap.add_argument('--max-growth-percent', type=float, default=10.0,
                    help='highest resident sample from frame 200 on, above the one at frame 200 (default 10)')
    ap.add_argument('--scene', default='flat', help='sgd_render scene of the synthetic drive (default flat)')
    ap.add_argument('--render-budget-s', type=float, default=600.0,
                    help='render fewer frames (and loop the bag) if rendering --frames would take longer')
    ap.add_argument('--cache', default='/tmp/sgd_soak', help='rendered sequences and bags, reused (/tmp/sgd_soak)')
    ap.add_argument('--bag', help='play this bag instead (stamps at 10 Hz from 1e9 s give frame numbers)')
    ap.add_argument('--sequence', help='with --bag: the folder it was made from (times.txt: frame numbers)')
    ap.add_argument('--stall-s', type=float, default=120.0, help='give up when no frame is processed for this long')
    ap.add_argument('--stereo-ns', default='/stereo')
    ap.add_argument('--log-dir', help='ROS_HOME of the run (node logs); default a new /tmp/sgd_soak_* folder')
    ap.add_argument('--json', help='also write the figures to this file')
    ap.add_argument('launch_args', nargs='*', help='extra NAME:=VALUE arguments of dem_nodelet.launch')
    args = ap.parse_args()
    if args.frames < args.every:
        ap.error('--frames must be at least --every')

    if args.bag:
        meta = dict(bag=args.bag, sequence=args.sequence or '', frames=None, bag_bytes=os.path.getsize(args.bag))
    else:
        try:
            meta = make_bag(args.cache, args.scene, args.frames, args.render_budget_s)
        except RuntimeError as e:
            print('soak: ' + str(e))
            return 2
    times = read_times(meta['sequence']) if meta.get('sequence') else []
    if meta.get('frames') is None and times:
        meta['frames'] = len(times)
    print('soak: bag %s: %s frames, %.2f GB' % (meta['bag'], meta.get('frames'), meta['bag_bytes'] / 1e9))
    sys.stdout.flush()

    result = soak(args, meta['bag'], times)
    rows, final = result['rows'], result['final']
    failures, loops = locate_failures(result, times)

    base_mark = 200 if args.frames >= 2 * 200 else args.every  # 100 for short runs
    mem = memory_figures(rows, base_mark)
    base = mem['base']
    diag = result['diag']
    mapped = sum(rt.diagnostic_count(diag, k) for k in ('initialized', 'tracked', 'recovered'))
    processed = final['processed']
    try:
        processing_mean_ms = float(diag.get('processing mean [ms]', 'nan'))
    except ValueError:
        processing_mean_ms = float('nan')

    problems = []
    if processed < args.frames:
        problems.append('only %d of %d frames processed (%s)' % (processed, args.frames,
                                                                result['stop_reason'] or 'stopped'))
    if final['failed'] != 0:
        problems.append('%d failed frames' % final['failed'])
    if final['skipped'] != 0:
        problems.append('%d skipped frames (invalid input)' % final['skipped'])
    if not (mem['max_growth_percent'] <= args.max_growth_percent):
        problems.append('resident memory rose by %.1f %% above frame %d\'s (bound %.1f %%)' % (
            mem['max_growth_percent'], base['processed'] if base else base_mark, args.max_growth_percent))

    kinds = {}
    for _, text in result['warnings']:
        kinds.setdefault(pattern(text), [0, text])[0] += 1
    print('soak: %d frames processed in %.0f s (%.2f frames/s; node processing mean %.0f ms): mapped %d '
          '(initialized %d, tracked %d, recovered %d), failed %d, dropped %d, skipped %d; %d map resets '
          '(%d bag loops seen in the odometry stamps)' % (
              processed, result['wall_s'], processed / result['wall_s'], processing_mean_ms, mapped,
              rt.diagnostic_count(diag, 'initialized'), rt.diagnostic_count(diag, 'tracked'),
              rt.diagnostic_count(diag, 'recovered'), final['failed'], final['dropped'], final['skipped'],
              final['resets'], loops))
    for line in memory_summary(mem, args.max_growth_percent, result['resident_before_mb']):
        print('soak: ' + line)
    for f in failures:
        print('soak: failed frame %s (loop %s, stamp %.3f): %s' % (f.get('frame', '?'), f.get('loop', '?'),
                                                                  f.get('stamp', float('nan')), f['message']))
    if kinds:
        print('soak: warnings and errors of the node on /rosout (kind: count, first):')
        for kind, (n, first) in sorted(kinds.items(), key=lambda kv: -kv[1][0]):
            print('  %5d  %s' % (n, first))
    if result['rebuilt_during_run']:
        print('soak: WARNING: libraries rebuilt during the run: ' + ', '.join(result['rebuilt_during_run']))
    print('soak: node logs in %s' % result['log_dir'])
    print('soak: ' + ('PASS' if not problems else 'FAIL: ' + '; '.join(problems)))

    if args.json:
        head, dirty = git_state()
        figures = dict(frames_target=args.frames, rate=args.rate, every=args.every, scene=args.scene,
                       bag=meta, rows=rows, final=final, mapped=mapped, processed=processed,
                       failed=final['failed'], dropped=final['dropped'], skipped=final['skipped'],
                       resets=final['resets'], loops=loops, processing_mean_ms=processing_mean_ms,
                       resident_growth_mb=mem['growth_mb'], resident_growth_percent=mem['growth_percent'],
                       resident_max_growth_percent=mem['max_growth_percent'],
                       memory={k: v for k, v in mem.items() if k not in ('base', 'last')},
                       max_growth_percent=args.max_growth_percent, resident_before_mb=result['resident_before_mb'],
                       wall_s=result['wall_s'], failures=failures,
                       warnings={k: v[0] for k, v in kinds.items()}, log_dir=result['log_dir'],
                       stop_reason=result['stop_reason'], rebuilt_during_run=result['rebuilt_during_run'],
                       git_head=head, git_modified=dirty, problems=problems, passed=not problems,
                       diagnostics=diag)
        with open(args.json, 'w') as f:
            json.dump(figures, f, indent=1)
    return 0 if not problems else 1


if __name__ == '__main__':
    sys.exit(main())
