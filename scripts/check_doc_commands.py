#!/usr/bin/env python3
"""Runs the shell commands of README.md and docs/ros.md as a user would after the README's set-up.

Extracts every command of README.md's ```bash blocks and of docs/ros.md's 4-space-indented code
blocks and inline `rosrun ...` / `roslaunch ...` spans (backslash-continued lines joined, trailing
`# comments` dropped), plus inline mentions of the package's programs in both files (`dem_offline
--list-parameters`, `kitti_to_bag --help`, ...), and judges each one:

  * the set-up / CI entry points (bash scripts/run_demo.sh, run_tests.sh, run_sanitizers.sh): NOT RUN,
    covered by CI (they build; this script only uses the built workspace);
  * usage synopses with placeholders ([--option ...], DIR, OUT, L.png, ...) and inline mentions: not
    run, but the program must exist and its --help (or its output without arguments) must print a
    usage line naming every option the synopsis names; NAME:=VALUE remaps and _private:=params of a
    `rosrun` synopsis must be names the node's binaries know;
  * every other command runs VERBATIM from the repository root in bash, after
    `source .catkin_ws/devel/setup.bash`, with ROS_MASTER_URI on a free port of its own (roslaunch
    starts that master itself; other commands that need a master get `roscore -p PORT`) and ROS_HOME
    in a temporary folder, with a timeout. roslaunch commands must first resolve (`roslaunch --nodes`);
    launch files that start rviz run under
    `LIBGL_ALWAYS_SOFTWARE=1 xvfb-run -a -s "-screen 0 1280x1024x24"` (as docs/ros.md says to run
    them headless); long-running launch files run until they produced what they must (the nodelet's
    "ready:" line naming the documented input topics, its topics and services, and for the bag
    playback DEMs on /stereo_ground_dem/dem and the bag played to its end), then a few seconds more,
    and are stopped with SIGINT like Ctrl-C; they fail on [ERROR]/[FATAL]/ERROR lines (except the one
    rviz line docs/ros.md documents as harmless), a process that died, a crash or heap error message, a
    node that had to be killed or exited non-zero at the stop. Launch files that need live hardware
    (stereo_camera.launch: a camera driver) are only checked with `roslaunch --nodes` plus the
    nodelet types they load, and say so.

One line per command (PASS / FAIL / NOT RUN, where, the command, why, seconds), a closing summary line;
exit status 1 on any FAIL, 2 when the workspace is not built. --junit FILE also writes JUnit XML (for
catkin_test_results). --list only prints the commands and how each would be judged; --only REGEX runs
the commands matching REGEX only. Uses the built workspace (.catkin_ws, or $SGD_WS), never builds.

    scripts/check_doc_commands.py [--junit FILE] [--list] [--only REGEX] [--keep-logs]
"""
import argparse
import glob
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PKG = 'stereo_ground_dem'
DOCS = [('README.md', 'bash-blocks'), ('docs/ros.md', 'indented-blocks')]

# the project's set-up / CI entry points: CI runs them, this script only uses what they built
CI_ENTRY = re.compile(r'^(?:bash\s+|sh\s+|\./)?scripts/(?:run_demo|run_tests|run_sanitizers)\.sh(?:\s|$)')

# launch files that need live hardware: started without it they would only wait; resolution is checked
LIVE_HARDWARE = {
    'stereo_camera.launch': 'needs a live stereo camera (a driver publishing CAMERA_NS/{left,right}/image_raw)',
}

# what a long-running launch file must produce before it is stopped, and its time limit [s]
NODE = '/' + PKG
LAUNCH_EXPECT = {
    'kitti_playback.launch': dict(ready=True, dem=True, bag_done=True, timeout=100,
                                  topics=[NODE + '/dem', NODE + '/traversability', NODE + '/odom'],
                                  services=[NODE + '/reset', NODE + '/save_map', NODE + '/load_map', NODE + '/get_submap']),
    'dem_nodelet.launch': dict(ready=True, dem=False, bag_done=False, timeout=60,
                               topics=[NODE + '/dem', NODE + '/dem_global', NODE + '/traversability',
                                       NODE + '/mesh', NODE + '/odom', NODE + '/path'],
                               services=[NODE + '/reset', NODE + '/save_map', NODE + '/load_map', NODE + '/get_submap']),
}
# the package's programs that are not ROS nodes (no master needed)
OFFLINE_PROGRAMS = {'dem_offline', 'kitti_to_bag', 'sgd_render', 'sgd_evaluate', 'sgd_long_run', 'sgd_benchmark'}
DEFAULT_LAUNCH_TIMEOUT = 40
GRACE_S = 3.0          # a launch keeps running this long after it produced everything (must not die)
COMMAND_TIMEOUT = 120  # one ordinary command

HEADLESS = 'LIBGL_ALWAYS_SOFTWARE=1 xvfb-run -a -s "-screen 0 1280x1024x24" '

ERROR_LINE = re.compile(r'\[\s*(?:ERROR|FATAL)\s*\]|\bERROR\b|\bFATAL\b')
# error lines that docs/ros.md documents as harmless (with the reason printed when seen)
ALLOWED_ERRORS = [
    (re.compile(r'rviz/glsl120/indexed_8bit_image\.vert .*GLSL link result : active samplers with a different type '
                r'refer to the same texture image unit'),
     "rviz's Mesa/llvmpipe shader-link message (indexed_8bit_image, GLSL link result) that docs/ros.md documents "
     "as harmless"),
]
CRASH = [r'double free', r'corruption', r'free\(\): invalid', r'munmap_chunk', r'malloc\(\)', r'Segmentation fault',
         r'Aborted', r'core dumped', r'terminate called', r'stack smashing', r'pure virtual method called']
ANSI = re.compile(r'\x1b\[[0-9;]*[A-Za-z]|\x1b\][^\x07]*\x07')
ENV_ASSIGN = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*=')


class Cmd(object):
    def __init__(self, doc, line, text, origin):
        self.doc, self.line, self.text, self.origin = doc, line, text, origin
        self.kind, self.why = None, ''
        self.status, self.reason, self.seconds, self.log = None, '', 0.0, ''

    @property
    def where(self):
        return '%s:%d' % (self.doc, self.line)


# ----------------------------------------------------------------------------------------- extraction

def strip_comment(line):
    """Drops a trailing `# comment` (a # that starts a word outside quotes)."""
    quote = None
    prev = ' '
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in '\'"':
            quote = ch
        elif ch == '#' and prev.isspace():
            return line[:i].rstrip()
        prev = ch
    return line.rstrip()


def logical_lines(numbered):
    """[(line number, text)] of a code block -> [(first line number, command)]: continuations joined,
    comments and blank lines dropped."""
    out, buf, start = [], None, 0
    for num, text in numbered:
        if buf is None:
            start, buf = num, ''
        stripped = text.rstrip()
        if stripped.endswith('\\'):
            buf += stripped[:-1].strip() + ' '
            continue
        buf += stripped.strip()
        cmd = strip_comment(buf).strip()
        buf = None
        if cmd and not cmd.startswith('#'):
            out.append((start, re.sub(r'\s+', ' ', cmd) if '"' not in cmd and "'" not in cmd else cmd))
    if buf:
        cmd = strip_comment(buf).strip()
        if cmd:
            out.append((start, cmd))
    return out


def inline_spans(lines, skip):
    """Backtick spans of the prose (lines whose index is not in `skip`), [(line number, text)]."""
    spans = []
    para, start = [], 0
    for i, text in enumerate(lines + ['']):
        if i < len(lines) and i not in skip and text.strip():
            if not para:
                start = i
            para.append(text)
            continue
        if para:
            joined = '\n'.join(para)
            for m in re.finditer(r'(`+)(.+?)\1', joined, re.S):
                spans.append((start + 1 + joined.count('\n', 0, m.start()), ' '.join(m.group(2).split())))
        para = []
    return spans


def extract(doc, mode, programs):
    with open(os.path.join(REPO, doc), encoding='utf-8') as f:
        lines = f.read().split('\n')
    cmds, code_lines = [], set()
    # fenced blocks
    fence, lang, block = None, '', []
    for i, text in enumerate(lines):
        m = re.match(r'^\s*(```+|~~~+)\s*([\w+-]*)', text)
        if fence is None and m:
            fence, lang, block = m.group(1), m.group(2).lower(), []
            code_lines.add(i)
            continue
        if fence is not None:
            code_lines.add(i)
            if text.strip().startswith(fence):
                if mode == 'bash-blocks' and lang in ('bash', 'sh', 'shell'):
                    cmds += [Cmd(doc, n, c, 'bash block') for n, c in logical_lines(block)]
                fence = None
            else:
                block.append((i + 1, text))
    # indented blocks (a blank line before, not a list item's continuation)
    prev_blank, in_block, in_list, block = True, False, False, []
    for i, text in enumerate(lines + ['']):
        if i in code_lines:
            prev_blank, in_block = False, False
            continue
        indented = (text.startswith('    ') or text.startswith('\t')) and text.strip()
        if indented and (in_block or (prev_blank and not in_list)):
            in_block = True
            block.append((i + 1, text[4:] if text.startswith('    ') else text[1:]))
            code_lines.add(i)
        elif in_block and not text.strip():
            pass  # a blank line inside a block
        else:
            if in_block and mode == 'indented-blocks':
                cmds += [Cmd(doc, n, c, 'indented block') for n, c in logical_lines(block)]
            in_block, block = False, []
            if text.strip():
                in_list = bool(re.match(r'^\s*(?:[-*+]|\d+\.)\s', text)) or (in_list and text.startswith(' '))
        prev_blank = not text.strip()
    # inline spans
    for num, span in inline_spans(lines, code_lines):
        try:
            words = shlex.split(span)
        except ValueError:
            continue
        if len(words) < 2:
            continue
        rest = [w for w in words if not ENV_ASSIGN.match(w)]
        first = rest[0] if rest else ''
        if mode == 'indented-blocks' and ('rosrun' in words or 'roslaunch' in words):
            cmds.append(Cmd(doc, num, span, 'inline'))
        elif first in programs or (first in ('bash', 'sh', 'python3') and len(rest) > 1 and rest[1].startswith('scripts/')) \
                or (first.startswith('scripts/') and os.path.exists(os.path.join(REPO, first))):
            cmds.append(Cmd(doc, num, span, 'inline mention'))
    cmds.sort(key=lambda c: c.line)
    return cmds


# ------------------------------------------------------------------------------------- environment

def workspace():
    return os.environ.get('SGD_WS') or os.path.join(REPO, '.catkin_ws')


def setup_line():
    ws = workspace()
    rel = os.path.relpath(ws, REPO)
    return 'source %s/devel/setup.bash' % (shlex.quote(rel) if not rel.startswith('..') else shlex.quote(ws))


def base_env():
    env = dict(os.environ)
    env['PATH'] = '/usr/bin:/bin:' + env.get('PATH', '')
    env['PYTHONUNBUFFERED'] = '1'              # roslaunch's own lines arrive when they are printed
    env['ROSCONSOLE_STDOUT_LINE_BUFFERED'] = '1'
    for k in ('ROS_IP', 'ROS_HOSTNAME', 'DISPLAY'):
        env.pop(k, None)
    return env


def sourced_env():
    """The environment after `source setup.bash` (for probes and program look-ups)."""
    p = subprocess.run(['bash', '-c', setup_line() + ' && env -0'], cwd=REPO, env=base_env(),
                       stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    env = {}
    for item in p.stdout.split(b'\0'):
        if b'=' in item:
            k, v = item.split(b'=', 1)
            env[k.decode()] = v.decode(errors='replace')
    return env


def free_port():
    s = socket.socket()
    s.bind(('127.0.0.1', 0))
    port = s.getsockname()[1]
    s.close()
    return port


def port_open(port):
    s = socket.socket()
    s.settimeout(0.3)
    try:
        s.connect(('127.0.0.1', port))
        return True
    except OSError:
        return False
    finally:
        s.close()


def package_programs():
    """The package's programs: CMakeLists.txt's add_executable targets and what the workspace holds
    (not the tests). From the sources too, so that a program missing from the build is reported."""
    names = set()
    with open(os.path.join(REPO, 'CMakeLists.txt')) as f:
        names |= set(re.findall(r'^\s*add_executable\(\s*([\w-]+)', f.read(), re.M))
    d = os.path.join(workspace(), 'devel', 'lib', PKG)
    if os.path.isdir(d):
        names |= {n for n in os.listdir(d) if os.access(os.path.join(d, n), os.X_OK)}
    return {n for n in names if not n.startswith('test_')}


def find_program(name, env, pkg=None):
    """Path of a program: `rosrun PKG name`, a repository path, or a name on PATH / in the workspace."""
    if pkg:
        cands = [os.path.join(workspace(), 'devel', 'lib', pkg, name), os.path.join('/usr/lib', pkg, name)]
        p = subprocess.run(['rospack', 'find', pkg], env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                           universal_newlines=True)
        if p.returncode == 0 and p.stdout.strip():
            cands += [os.path.join(p.stdout.strip(), sub, name) for sub in ('', 'scripts', 'nodes')]
        return next((c for c in cands if os.path.isfile(c) and os.access(c, os.X_OK)), None)
    if '/' in name:
        path = os.path.join(REPO, name)
        return path if os.path.isfile(path) else None
    found = shutil.which(name, path=env.get('PATH'))
    if found:
        return found
    for c in (os.path.join(workspace(), 'devel', 'lib', PKG, name), os.path.join(REPO, 'scripts', name)):
        if os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    return None


def binary_mtimes():
    out = {}
    for root, _, files in os.walk(os.path.join(workspace(), 'devel', 'lib')):
        for n in files:
            p = os.path.join(root, n)
            try:
                out[p] = os.stat(p).st_mtime
            except OSError:
                pass
    return out


# ---------------------------------------------------------------------------------- classification

def words_of(text):
    try:
        return shlex.split(text)
    except ValueError:
        return None


def placeholders(words):
    found = []
    for w in words:
        if ENV_ASSIGN.match(w) and '...' not in w:
            continue
        if '...' in w or '[' in w or ']' in w or re.fullmatch(r'[A-Z][A-Z0-9_]*(?:\.[a-z0-9]+)?', w):
            found.append(w)
    return found


def command_words(words):
    """The words after leading VAR=value assignments and wrappers (xvfb-run and its options)."""
    i = 0
    while i < len(words) and ENV_ASSIGN.match(words[i]):
        i += 1
    if i < len(words) and os.path.basename(words[i]) == 'xvfb-run':
        i += 1
        while i < len(words) and words[i].startswith('-'):
            if words[i] in ('-s', '-n', '-e', '-f', '-p', '-w'):
                i += 1
            i += 1
    return words[i:]


def classify(c, env):
    words = words_of(c.text)
    if words is None:
        c.kind, c.why = 'fail', 'the shell cannot parse it (unbalanced quotes)'
        return
    cw = command_words(words)
    first = cw[0] if cw else ''
    if CI_ENTRY.match(c.text):
        c.kind, c.why = 'ci', 'covered by CI (the set-up / CI entry point: installs, builds and runs)'
        return
    if re.search(r'-->|<--|->', c.text) and not find_program(first, env):
        c.kind, c.why = 'text', 'not a shell command (a diagram in a code block)'
        return
    ph = placeholders(words)
    fragment = first in ('rosrun', 'roslaunch') and len([w for w in cw[1:] if not w.startswith('-')]) < 1
    if c.origin == 'inline mention':
        c.kind = 'synopsis'
        c.why = 'inline mention' + (' with placeholders %s' % ' '.join(ph) if ph else '')
    elif ph:
        c.kind, c.why = 'synopsis', 'usage synopsis with placeholders %s' % ' '.join(ph)
    elif fragment:
        c.kind, c.why = 'synopsis', 'fragment of a command (no package / launch file)'
    elif first == 'roslaunch':
        name = launch_file(cw)
        if name in LIVE_HARDWARE:
            c.kind, c.why = 'hardware', LIVE_HARDWARE[name]
        else:
            c.kind, c.why = 'launch', 'long-running launch file'
    else:
        c.kind, c.why = 'run', ''


def launch_file(cw):
    pos = [w for w in cw[1:] if not w.startswith('-') and ':=' not in w]
    if not pos:
        return ''
    return os.path.basename(pos[1] if len(pos) > 1 and not pos[0].endswith('.launch') else pos[0])


def launch_args(cw):
    """roslaunch words -> (positional + NAME:=VALUE) for `roslaunch --nodes`, and the NAME:=VALUE dict."""
    keep, args, skip = [], {}, False
    for w in cw[1:]:
        if skip:
            skip = False
            continue
        if w in ('-p', '--port', '--args', '--find', '--log', '--pid', '-u', '--server_uri', '--run_id'):
            skip = True
            continue
        if w.startswith('-'):
            continue
        keep.append(w)
        if ':=' in w:
            k, v = w.split(':=', 1)
            args[k] = v
    return keep, args


# ------------------------------------------------------------------------------------------ checks

def check_synopsis(c, env):
    """The program exists; its usage names every option; remaps / private params are names it knows."""
    words = [w.strip('[]') for w in words_of(c.text)]
    notes, problems, segments = [], [], []
    cw = command_words(words)
    wrapper = [w for w in words[:len(words) - len(cw)] if not ENV_ASSIGN.match(w)]
    if wrapper:  # xvfb-run and its options
        segments.append((wrapper[0], None, wrapper[1:]))
    if not cw:
        return 'FAIL', 'no program in it'
    if cw[0] in ('bash', 'sh', 'python3') and len(cw) > 1:
        segments.append((cw[1], None, cw[2:]))
    elif cw[0] == 'rosrun' and len(cw) > 2:
        segments.append((cw[2], cw[1], cw[3:]))
    else:
        segments.append((cw[0], None, cw[1:]))
    for prog, pkg, args in segments:
        path = find_program(prog, env, pkg)
        label = ('rosrun %s %s' % (pkg, prog)) if pkg else prog
        if not path:
            problems.append('%s: no such program' % label)
            continue
        options = [a for a in args if re.fullmatch(r'--?[A-Za-z][\w-]*', a)]
        ros_names = [a.split(':=', 1)[0] for a in args if ':=' in a]
        if options:
            text, help_rc = '', None
            for argv in ([path, '--help'], [path]):
                try:
                    p = subprocess.run(argv, env=env, cwd=REPO, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                       stderr=subprocess.STDOUT, universal_newlines=True, timeout=15)
                    text, rc = p.stdout, p.returncode
                except subprocess.TimeoutExpired as e:
                    text = (e.stdout or b'').decode(errors='replace') if isinstance(e.stdout, bytes) else (e.stdout or '')
                    rc = 'timeout'
                if help_rc is None:
                    help_rc = rc
                if re.search(r'usage', text, re.I):
                    break
            if not re.search(r'usage', text, re.I):
                problems.append('%s: neither --help nor no arguments prints a usage line' % label)
                continue
            # --help itself is not named in a usage; it must print the usage and exit 0
            if '--help' in options or '-h' in options:
                if help_rc != 0:
                    problems.append('%s --help exits %s' % (label, help_rc))
                options = [o for o in options if o not in ('--help', '-h')]
                notes.append('%s --help prints its usage and exits 0' % label)
            missing = [o for o in options if not re.search(r'(?<![\w-])%s(?![\w-])' % re.escape(o), text)]
            if missing:
                problems.append('%s: its usage does not name %s' % (label, ' '.join(missing)))
            elif options:
                notes.append('%s usage names %s' % (label, ' '.join(options)))
        if ros_names:
            blobs = [path]
            if pkg == PKG or path.startswith(os.path.join(workspace(), 'devel')):
                blobs += glob.glob(os.path.join(workspace(), 'devel', 'lib', 'lib%s*.so' % PKG))
            data = b''
            for b in blobs:
                with open(b, 'rb') as f:
                    data += f.read()
            unknown = [n for n in ros_names if n.lstrip('_~').encode() not in data]
            if unknown:
                problems.append('%s: its binaries do not know %s' % (label, ' '.join(unknown)))
            else:
                notes.append('%s knows %s' % (label, ' '.join(ros_names)))
        if not options and not ros_names:
            notes.append('%s exists' % label)
    if problems:
        return 'FAIL', '%s; %s' % (c.why, '; '.join(problems))
    return 'PASS', 'not run (%s): %s' % (c.why, '; '.join(notes))


def run_bash(script, env, timeout, log_path):
    with open(log_path, 'w') as out:
        p = subprocess.Popen(['bash', '-c', script], cwd=REPO, env=env, stdin=subprocess.DEVNULL, stdout=out,
                             stderr=subprocess.STDOUT, start_new_session=True)
        try:
            rc = p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            kill_group(p)
            rc = 'timeout'
    with open(log_path, errors='replace') as f:
        return rc, ANSI.sub('', f.read())


def kill_group(p, first=signal.SIGTERM):
    for sig in (first, signal.SIGKILL):
        try:
            os.killpg(p.pid, sig)
        except ProcessLookupError:
            return
        try:
            p.wait(timeout=10)
            return
        except subprocess.TimeoutExpired:
            pass


def needs_master(cw):
    if not cw:
        return False
    if cw[0] == 'rosrun':
        return not (len(cw) > 2 and cw[1] == PKG and cw[2] in OFFLINE_PROGRAMS)
    if cw[0] == 'rosbag':
        return len(cw) > 1 and cw[1] in ('play', 'record')
    return cw[0] in ('rostopic', 'rosservice', 'rosparam', 'rosnode', 'rosmsg-proto')


def last_lines(text, n=3):
    lines = [l for l in text.strip().splitlines() if l.strip() and 'File system loop detected' not in l]
    return ' | '.join(l.strip()[:200] for l in lines[-n:])


def command_env(tmp):
    env = base_env()
    port = free_port()
    env['ROS_MASTER_URI'] = 'http://127.0.0.1:%d' % port
    env['ROS_HOME'] = tmp
    return env, port


def run_plain(c, tmp):
    words = words_of(c.text)
    cw = command_words(words)
    env, port = command_env(tmp)
    # a fresh machine has none of the command's outputs: remove the files it writes with --out
    for i, w in enumerate(words[:-1]):
        if w == '--out' and words[i + 1].startswith('/tmp/') and os.path.isfile(words[i + 1]):
            os.remove(words[i + 1])
    master = None
    if needs_master(cw):
        master = subprocess.Popen(['bash', '-c', setup_line() + ' && exec roscore -p %d' % port], cwd=REPO, env=env,
                                  stdin=subprocess.DEVNULL, stdout=open(os.path.join(tmp, 'roscore.txt'), 'w'),
                                  stderr=subprocess.STDOUT, start_new_session=True)
        end = time.time() + 30
        while time.time() < end and not port_open(port):
            time.sleep(0.2)
    try:
        rc, out = run_bash(setup_line() + ' && ' + c.text, env, COMMAND_TIMEOUT, os.path.join(tmp, 'output.txt'))
    finally:
        if master:
            kill_group(master, signal.SIGINT)
    extra = ' (with a roscore of its own)' if master else ''
    if rc == 0:
        tail = last_lines(out, 1)
        return 'PASS', 'exit 0%s%s' % (extra, ': ' + tail if tail else '')
    if rc == 'timeout':
        return 'FAIL', 'still running after %d s%s: %s' % (COMMAND_TIMEOUT, extra, last_lines(out))
    return 'FAIL', 'exit %s%s: %s' % (rc, extra, last_lines(out))


def launch_error(out):
    """The reason in roslaunch's error output (its first error line), with a hint for a missing package."""
    lines = [l.strip() for l in out.splitlines() if l.strip() and 'File system loop detected' not in l]
    err = next((l for l in lines if re.search(r'not found|error|exception|invalid|cannot|unable', l, re.I)
                and 'traceback for the exception' not in l), None)
    text = err or ' | '.join(lines[-3:])
    m = re.search(r'Resource not found: (\S+)', text)
    if m:
        text += ' (no ROS package %s on the ROS path: its package.xml / launch files are not installed)' % m.group(1)
    return text


def resolve_launch(cw, env, tmp):
    keep, _ = launch_args(cw)
    rc, out = run_bash(setup_line() + ' && roslaunch --nodes ' + ' '.join(shlex.quote(w) for w in keep),
                       env, 60, os.path.join(tmp, 'nodes.txt'))
    nodes = [l.strip() for l in out.splitlines() if l.startswith('/')]
    return rc, out, nodes


def nodelet_types(cw, env, tmp):
    """(types loaded by `nodelet load` in the launch file, types declared by installed plugins)."""
    keep, _ = launch_args(cw)
    script = r'''
import sys, roslaunch.config, roslaunch.rlutil
args = sys.argv[1:]
files = roslaunch.rlutil.resolve_launch_arguments([a for a in args if ':=' not in a])
sys.argv = ['roslaunch'] + args  # the loader reads NAME:=VALUE from sys.argv, as roslaunch does
cfg = roslaunch.config.load_config_default(files, None, verbose=False)
for n in cfg.nodes:
    a = n.args.split()
    if n.package == 'nodelet' and len(a) > 1 and a[0] in ('load', 'standalone'):
        print('TYPE ' + a[1])
'''
    p = subprocess.run(['/usr/bin/python3', '-c', script] + keep, cwd=REPO, env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, universal_newlines=True, timeout=60)
    wanted = [l[5:].strip() for l in p.stdout.splitlines() if l.startswith('TYPE ')]
    q = subprocess.run(['rospack', 'plugins', '--attrib=plugin', 'nodelet'], env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.DEVNULL, universal_newlines=True)
    declared = set()
    for line in q.stdout.splitlines():
        parts = line.split()
        if len(parts) == 2 and os.path.isfile(parts[1]):
            with open(parts[1], errors='replace') as f:
                declared |= set(re.findall(r'<class[^>]*\bname="([^"]+)"', f.read()))
    return wanted, declared, p


def check_hardware(c, tmp):
    cw = command_words(words_of(c.text))
    env, _ = command_env(tmp)
    senv = sourced_env()
    rc, out, nodes = resolve_launch(cw, env, tmp)
    limitation = 'not run: %s, absent here; checked only that it resolves (roslaunch --nodes)' % c.why
    if rc != 0 or not nodes:
        return 'FAIL', '%s: roslaunch --nodes failed (exit %s): %s' % (limitation, rc, launch_error(out))
    wanted, declared, p = nodelet_types(cw, senv, tmp)
    if p.returncode != 0:
        return 'FAIL', '%s: %d nodes resolve, but the nodelet types could not be read: %s' % (
            limitation, len(nodes), last_lines(p.stdout))
    missing = [t for t in wanted if t not in declared]
    if missing:
        return 'FAIL', '%s: %d nodes resolve, but no installed plugin declares the nodelet types %s' % (
            limitation, len(nodes), ' '.join(missing))
    return 'PASS', '%s and its nodelet types are installed: %d nodes resolve (%s), nodelets %s' % (
        limitation, len(nodes), ' '.join(nodes), ' '.join(sorted(set(wanted))))


def find_roslaunch_pid(pgid):
    """The roslaunch process in the command's session (below bash / xvfb-run)."""
    for d in os.listdir('/proc'):
        if not d.isdigit():
            continue
        try:
            if os.getpgid(int(d)) != pgid:
                continue
            with open('/proc/%s/cmdline' % d, 'rb') as f:
                argv = f.read().split(b'\0')
        except (OSError, ProcessLookupError):
            continue
        if any(os.path.basename(a) == b'roslaunch' for a in argv[:2]):
            return int(d)
    return None


def check_launch(c, tmp):
    words = words_of(c.text)
    cw = command_words(words)
    env, port = command_env(tmp)
    name = launch_file(cw)
    _, largs = launch_args(cw)
    expect = LAUNCH_EXPECT.get(name, dict(ready=False, dem=False, bag_done=False, timeout=DEFAULT_LAUNCH_TIMEOUT,
                                          topics=[], services=[]))
    t0 = time.time()
    rc, out, nodes = resolve_launch(cw, env, tmp)
    if rc != 0 or not nodes:
        return 'FAIL', 'roslaunch --nodes failed (exit %s): %s' % (rc, launch_error(out))
    command = c.text
    headless = any(n.rstrip('/').split('/')[-1].startswith('rviz') for n in nodes) and 'xvfb-run' not in words
    if headless:
        command = HEADLESS + c.text
    senv = sourced_env()
    senv.update({k: env[k] for k in ('ROS_MASTER_URI', 'ROS_HOME')})
    log_path = os.path.join(tmp, 'output.txt')
    out_f = open(log_path, 'w')
    proc = subprocess.Popen(['bash', '-c', setup_line() + ' && ' + command], cwd=REPO, env=env,
                            stdin=subprocess.DEVNULL, stdout=out_f, stderr=subprocess.STDOUT, start_new_session=True)
    probe, probe_path, dems = None, os.path.join(tmp, 'dem_probe.txt'), 0
    ready_line, listed, satisfied_at, died, problems = None, None, None, None, []
    end = t0 + expect['timeout']
    text = ''
    try:
        while time.time() < end:
            time.sleep(0.5)
            with open(log_path, errors='replace') as f:
                text = ANSI.sub('', f.read())
            if proc.poll() is not None:
                died = 'roslaunch ended (exit %s) after %.0f s, before it was stopped' % (proc.returncode, time.time() - t0)
                break
            if 'has died' in text:
                died = 'a process died: ' + next(l.strip() for l in text.splitlines() if 'has died' in l)[:300]
                break
            if ready_line is None:
                m = re.search(r'^.*\]: ready: .*$', text, re.M)
                ready_line = m.group(0) if m else None
            if expect['dem'] and (probe is None or probe.poll() is not None) and port_open(port):
                probe = subprocess.Popen(['rostopic', 'echo', NODE + '/dem/info/header/seq'], env=senv,
                                         stdin=subprocess.DEVNULL, stdout=open(probe_path, 'a'),
                                         stderr=subprocess.STDOUT, start_new_session=True)
            if probe is not None:
                with open(probe_path, errors='replace') as f:
                    dems = f.read().count('\n---')
            if ready_line and listed is None and (expect['topics'] or expect['services']):
                time.sleep(0.5)
                lrc, lout = run_bash('rostopic list; rosservice list', senv, 30, os.path.join(tmp, 'list.txt'))
                listed = set(l.strip() for l in lout.splitlines())
            bag_done = re.search(r'\[player[^\]]*\] process has finished cleanly', text) is not None
            done = ((ready_line or not expect['ready']) and (dems > 0 or not expect['dem'])
                    and (bag_done or not expect['bag_done'])
                    and (listed is not None or not (expect['topics'] or expect['services'])))
            if done and satisfied_at is None:
                satisfied_at = time.time()
            if satisfied_at is not None and time.time() > satisfied_at + GRACE_S:
                break
        ran_s = time.time() - t0
        # stop it as Ctrl-C does: SIGINT to roslaunch, which stops its nodes with SIGINT
        stopped_cleanly = True
        if proc.poll() is None:
            pid = find_roslaunch_pid(proc.pid)
            try:
                os.kill(pid, signal.SIGINT) if pid else os.killpg(proc.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
            try:
                proc.wait(timeout=40)
            except subprocess.TimeoutExpired:
                stopped_cleanly = False
                kill_group(proc)
    finally:
        if probe is not None and probe.poll() is None:
            kill_group(probe, signal.SIGINT)
        if proc.poll() is None:
            kill_group(proc)
        out_f.close()
    with open(log_path, errors='replace') as f:
        text = ANSI.sub('', f.read())
    launch_log = ''
    for lg in glob.glob(os.path.join(tmp, 'log', '*', 'roslaunch-*.log')):
        with open(lg, errors='replace') as f:
            launch_log += f.read()
    # judge
    if died:
        problems.append(died)
    if satisfied_at is None and not died:
        missing = []
        if expect['ready'] and not ready_line:
            missing.append('the nodelet\'s "ready:" line')
        if expect['dem'] and dems == 0:
            missing.append('a DEM on %s/dem' % NODE)
        if expect['bag_done'] and not re.search(r'\[player[^\]]*\] process has finished cleanly', text):
            missing.append('the bag played to its end')
        if missing:
            problems.append('after %.0f s still no %s' % (expect['timeout'], ', no '.join(missing)))
    if ready_line and 'stereo_ns' in largs:
        want = largs['stereo_ns'].rstrip('/') + '/left/image_rect'
        if want not in ready_line:
            problems.append('the ready line does not name %s: %s' % (want, ready_line.split(']: ', 1)[-1]))
    if listed is not None:
        absent = [t for t in expect['topics'] + expect['services'] if t not in listed]
        if absent:
            problems.append('not advertised: %s' % ' '.join(absent))
    allowed_seen = []
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if ERROR_LINE.search(line):
            # the message with its continuation lines (up to the next line that starts a new message)
            msg = [line]
            for nxt in lines[i + 1:i + 8]:
                if nxt.lstrip().startswith('[') or not nxt.strip() and len(msg) > 1:
                    break
                msg.append(nxt)
            msg = ' '.join(' '.join(msg).split())
            why = next((w for rx, w in ALLOWED_ERRORS if rx.search(msg)), None)
            if why:
                allowed_seen.append(why)
            else:
                problems.append('error line: ' + msg[:300])
    for bad in CRASH:
        m = re.search(r'^.*%s.*$' % bad, text + '\n' + launch_log, re.M)
        if m:
            problems.append('crash / heap error: ' + m.group(0).strip()[:300])
    if 'escalating to SIG' in text + launch_log or not stopped_cleanly:
        problems.append('a process did not end within the stop timeout after SIGINT')
    for node, r in re.findall(r'process\[([^\]]+)\]: SIGINT killed with return value (-?\d+)', launch_log):
        if int(r) != 0 and not node.startswith('rviz'):
            problems.append('%s exited with %s on SIGINT' % (node, r))
    got = []
    if ready_line:
        got.append('"ready:" line naming %s' % ', '.join(re.findall(r'/[\w/]+image_rect', ready_line)[:1] or ['?']))
    if expect['dem']:
        got.append('%d DEMs on %s/dem' % (dems, NODE))
    if expect['bag_done'] and re.search(r'\[player[^\]]*\] process has finished cleanly', text):
        got.append('bag played to its end')
    if listed is not None:
        got.append('%d topics and services advertised' % len([t for t in expect['topics'] + expect['services']
                                                            if t in listed]))
    summary = '%s%sran %.0f s, stopped with SIGINT: %s' % (
        'under Xvfb + software GL; ' if headless else '', '%d nodes resolve; ' % len(nodes), ran_s,
        ', '.join(got) or ('none of what it must produce' if expect['ready'] or expect['dem']
                           else 'nothing expected beyond staying up'))
    if allowed_seen:
        summary += '; allowed: ' + '; '.join(sorted(set(allowed_seen)))
    if problems:
        return 'FAIL', summary + '; PROBLEMS: ' + '; '.join(problems[:5])
    return 'PASS', summary + '; no error lines, nothing died, clean stop'


# -------------------------------------------------------------------------------------------- main

def xml_text(s):
    return re.sub(r'[\x00-\x08\x0b\x0c\x0e-\x1f]', '', s)


def write_junit(path, cmds, total_s):
    suite = ET.Element('testsuite', name='doc_commands', tests=str(len(cmds)),
                       failures=str(sum(c.status == 'FAIL' for c in cmds)), errors='0',
                       skipped=str(sum(c.status == 'NOT RUN' for c in cmds)), time='%.1f' % total_s)
    for c in cmds:
        case = ET.SubElement(suite, 'testcase', classname='doc_commands.' + c.doc.replace('/', '_').replace('.', '_'),
                             name=xml_text('%s %s' % (c.where, c.text[:120])), time='%.1f' % c.seconds)
        if c.status == 'FAIL':
            ET.SubElement(case, 'failure', message=xml_text(c.reason[:500]), type='DocCommandFailed').text = \
                xml_text(c.reason)
        elif c.status == 'NOT RUN':
            ET.SubElement(case, 'skipped', message=xml_text(c.reason[:500]))
        ET.SubElement(case, 'system-out').text = xml_text('%s\n%s' % (c.reason, c.log))
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    ET.ElementTree(suite).write(path, encoding='utf-8', xml_declaration=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--junit', help='also write JUnit XML here (for catkin_test_results)')
    ap.add_argument('--list', action='store_true', help='print the commands and their kinds, run nothing')
    ap.add_argument('--only', help='run only the commands matching this regular expression')
    ap.add_argument('--keep-logs', action='store_true', help='keep the per-command logs (printed folder)')
    args = ap.parse_args()
    t_start = time.time()
    setup = os.path.join(workspace(), 'devel', 'setup.bash')
    if not os.path.isfile(setup):
        print('check_doc_commands: %s missing: build first (bash scripts/build.sh or scripts/run_tests.sh)' % setup)
        return 2
    env = sourced_env()
    programs = package_programs()
    cmds = []
    for doc, mode in DOCS:
        cmds += extract(doc, mode, programs)
    for c in cmds:
        classify(c, env)
    if args.list:
        for c in cmds:
            print('%-9s %-16s %s  [%s] %s' % (c.kind, c.where, c.text, c.origin, c.why))
        return 0
    if args.only:
        cmds = [c for c in cmds if re.search(args.only, c.text)]
    logs = tempfile.mkdtemp(prefix='sgd_doc_commands_')
    before = binary_mtimes()
    done = {}
    for k, c in enumerate(cmds):
        t0 = time.time()
        tmp = os.path.join(logs, '%02d' % k)
        os.makedirs(tmp)
        if c.text in done and c.kind not in ('ci', 'text'):
            first = done[c.text]
            c.status, c.reason = first.status, 'same command as %s: %s' % (first.where, first.status)
        elif c.kind == 'ci':
            c.status, c.reason = 'NOT RUN', c.why
        elif c.kind == 'text':
            c.status, c.reason = 'NOT RUN', c.why
        elif c.kind == 'fail':
            c.status, c.reason = 'FAIL', c.why
        elif c.kind == 'synopsis':
            c.status, c.reason = check_synopsis(c, env)
        elif c.kind == 'hardware':
            c.status, c.reason = check_hardware(c, tmp)
        elif c.kind == 'launch':
            c.status, c.reason = check_launch(c, tmp)
        else:
            c.status, c.reason = run_plain(c, tmp)
        done.setdefault(c.text, c)
        c.seconds = time.time() - t0
        out = os.path.join(tmp, 'output.txt')
        if os.path.isfile(out):
            with open(out, errors='replace') as f:
                c.log = ANSI.sub('', f.read())[-20000:]
        print('%-7s %s  %s  -- %s (%.1f s)' % (c.status, c.where, c.text, c.reason, c.seconds), flush=True)
    total = time.time() - t_start
    if binary_mtimes() != before:
        print('WARNING: binaries in %s/devel/lib changed during this run (a concurrent build?): '
              'the results above may not be reliable' % workspace())
    if args.junit:
        write_junit(args.junit, cmds, total)
    if args.keep_logs:
        print('logs: %s' % logs)
    else:
        shutil.rmtree(logs, ignore_errors=True)
    n_pass = sum(c.status == 'PASS' for c in cmds)
    n_fail = sum(c.status == 'FAIL' for c in cmds)
    n_skip = sum(c.status == 'NOT RUN' for c in cmds)
    print('%d commands of README.md and docs/ros.md checked in %.0f s' % (len(cmds), total))
    print('doc_commands: %d passed, %d failed, %d skipped' % (n_pass, n_fail, n_skip))
    return 1 if n_fail else 0


if __name__ == '__main__':
    sys.exit(main())
