"""The RViz plugins load: rviz_plugins.xml is exported and matches the library, and an RViz
started under Xvfb with rviz/mapping.rviz instantiates every plugin without a loading error,
subscribes to the package's topics and draws the loop candidates and removed points of a
synthetic scene (scripts/rviz_publish_map.py --synthetic).

Run by `catkin_make run_tests` (target run_tests_multisession_mapper_pytest_rviz_plugins, which
passes the built library in MSM_RVIZ_LIBRARY) inside the workspace environment. Skipped only
when the Xvfb, rviz or import (ImageMagick) executables are absent.
"""
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import xml.etree.ElementTree as ElementTree
import xmlrpc.client

import numpy as np
import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PLUGINS_XML = os.path.join(REPO, 'rviz_plugins.xml')
RVIZ_CONFIG = os.path.join(REPO, 'rviz', 'mapping.rviz')
PUBLISHER = os.path.join(REPO, 'scripts', 'rviz_publish_map.py')
EXPECTED_CLASSES = {
    'multisession_mapper/LoopCandidates': 'rviz::Display',
    'multisession_mapper/DynamicPoints': 'rviz::Display',
    'multisession_mapper/MapSessionPanel': 'rviz::Panel',
}
# Topics the two displays and the panel of mapping.rviz subscribe to.
PLUGIN_TOPICS = ['/loop_candidates', '/dynamic_points', '/submaps', '/change_summary']
# What RViz prints when a plugin cannot be created.
LOAD_ERRORS = ['PluginlibFactory: The plugin for class', 'Failed to load', 'failed to load',
               'Could not load library', 'Segmentation fault', 'terminate called']
WIDTH, HEIGHT = 1280, 800


def plugin_classes():
    root = ElementTree.parse(PLUGINS_XML).getroot()
    return root.get('path'), [(c.get('name'), c.get('type'), c.get('base_class_type'))
                              for c in root.iter('class')]


def plugin_library():
    path = os.environ.get('MSM_RVIZ_LIBRARY')
    if path:
        return path
    for folder in os.environ.get('LD_LIBRARY_PATH', '').split(os.pathsep):
        candidate = os.path.join(folder, 'libmultisession_mapper_rviz.so')
        if folder and os.path.isfile(candidate):
            return candidate
    pytest.fail('libmultisession_mapper_rviz.so not found: set MSM_RVIZ_LIBRARY or source '
                'the workspace (devel/setup.bash)')


@pytest.fixture
def ros_home():
    path = tempfile.mkdtemp(prefix='msm_rviz_test_')
    yield path
    shutil.rmtree(path, ignore_errors=True)


def test_description_declares_every_plugin():
    library, classes = plugin_classes()
    assert library == 'lib/libmultisession_mapper_rviz'
    assert {name: base for name, _, base in classes} == EXPECTED_CLASSES
    for name, class_type, _ in classes:
        assert class_type.startswith('multisession_mapper::rviz_plugins::'), name


def test_rospack_finds_the_exported_description(ros_home):
    env = dict(os.environ, ROS_HOME=ros_home)
    out = subprocess.run(['rospack', 'plugins', '--attrib=plugin', 'rviz'], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    exported = [line.split(None, 1) for line in out.stdout.splitlines() if line.strip()]
    ours = [os.path.realpath(path.strip()) for pkg, path in exported
            if pkg == 'multisession_mapper']
    assert ours == [os.path.realpath(PLUGINS_XML)], out.stdout


def test_library_registers_every_class_with_its_base():
    library = plugin_library()
    _, classes = plugin_classes()
    assert os.path.basename(library) == 'libmultisession_mapper_rviz.so'
    symbols = subprocess.run(['nm', '-C', '--defined-only', library], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, check=True).stdout
    for name, class_type, base in classes:
        # PLUGINLIB_EXPORT_CLASS instantiates class_loader's registerPlugin<Derived, Base>.
        registration = 'class_loader::impl::registerPlugin<%s, %s>' % (class_type, base)
        assert registration in symbols, '%s: %s missing from %s' % (name, registration, library)


# ---------------------------------------------------------------------------------------------
# RViz under Xvfb
# ---------------------------------------------------------------------------------------------
def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def start_xvfb():
    """Xvfb on a display it picks itself (-displayfd): (process, ':N')."""
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(['Xvfb', '-displayfd', str(write_fd), '-screen', '0',
                             '%dx%dx24' % (WIDTH, HEIGHT), '+extension', 'GLX', '+render',
                             '-noreset', '-nolisten', 'tcp'],
                            pass_fds=(write_fd,), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    os.close(write_fd)
    with os.fdopen(read_fd) as f:
        number = f.readline().strip()
    if not number:
        proc.kill()
        pytest.fail('Xvfb did not report a display number')
    return proc, ':' + number


def subscribers(master_uri):
    """topic -> set of subscribing node names, from the master."""
    state = xmlrpc.client.ServerProxy(master_uri).getSystemState('/rviz_plugins_test')
    return {topic: set(nodes) for topic, nodes in state[2][1]}


def wait_for(predicate, timeout_s, step_s=0.5):
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        try:
            if predicate():
                return True
        except (OSError, xmlrpc.client.Error):
            pass
        time.sleep(step_s)
    return False


def screenshot(display, path):
    """(H, W, 3) uint8 of the X screen."""
    subprocess.run(['import', '-display', display, '-window', 'root', '-depth', '8',
                    'rgb:' + path], check=True, timeout=60)
    return np.fromfile(path, dtype=np.uint8).reshape(HEIGHT, WIDTH, 3).astype(np.int32)


def stop(proc):
    if proc is not None and proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_rviz_loads_mapping_config_under_xvfb(ros_home):
    for tool in ('Xvfb', 'rviz', 'import'):
        if shutil.which(tool) is None:
            pytest.skip('%s is not installed (scripts/test.sh installs it)' % tool)
    port = free_port()
    master_uri = 'http://localhost:%d' % port
    env = dict(os.environ, ROS_HOME=ros_home, ROS_MASTER_URI=master_uri,
               ROS_HOSTNAME='localhost', ROS_LOG_DIR=os.path.join(ros_home, 'log'))
    env.pop('ROS_IP', None)
    rviz_log_path = os.path.join(ros_home, 'rviz.log')
    xvfb = roscore = rviz = publisher = None
    try:
        xvfb, display = start_xvfb()
        env['DISPLAY'] = display
        roscore = subprocess.Popen(['roscore', '-p', str(port)], env=env,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        assert wait_for(lambda: subscribers(master_uri) is not None, 30), 'roscore did not start'

        with open(rviz_log_path, 'w') as rviz_log:
            rviz = subprocess.Popen(['rviz', '-d', RVIZ_CONFIG], env=env, stdout=rviz_log,
                                    stderr=subprocess.STDOUT)
        started = time.time()

        def plugins_subscribed():
            subs = subscribers(master_uri)
            return all(any(n.startswith('/rviz') for n in subs.get(t, ())) for t in PLUGIN_TOPICS)

        subscribed = wait_for(plugins_subscribed, 60)
        assert rviz.poll() is None, 'rviz exited with %s' % rviz.returncode
        assert subscribed, 'rviz did not subscribe to %s: %s' % (PLUGIN_TOPICS,
                                                                  subscribers(master_uri))
        before = screenshot(display, os.path.join(ros_home, 'before.rgb'))

        publisher = subprocess.Popen(['/usr/bin/python3', PUBLISHER, '--synthetic',
                                      '--duration', '60'], env=env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(max(15.0 - (time.time() - started), 8.0))
        assert rviz.poll() is None, 'rviz exited with %s' % rviz.returncode
        after = screenshot(display, os.path.join(ros_home, 'after.rgb'))
    finally:
        for proc in (publisher, rviz, roscore):
            stop(proc)
        if xvfb is not None:
            xvfb.kill()
            xvfb.wait()

    with open(rviz_log_path, errors='replace') as f:
        log = f.read()
    for error in LOAD_ERRORS:
        assert error not in log, 'rviz reported "%s":\n%s' % (error, log[-4000:])

    def count(img, color):
        # Displays draw unlit flat colours; allow for blending at edges.
        return int(np.sum(np.all(np.abs(img - np.array(color)) <= 40, axis=2)))

    # Removed points are red (255, 0, 0), held-back points violet (130, 60, 255), accepted loops
    # green (0, 210, 90) in mapping.rviz; none of these colours is on screen before the scene is
    # published.
    red_before, red_after = count(before, (255, 0, 0)), count(after, (255, 0, 0))
    violet_before, violet_after = count(before, (130, 60, 255)), count(after, (130, 60, 255))
    green_before, green_after = count(before, (0, 210, 90)), count(after, (0, 210, 90))
    assert red_after > red_before + 200, (red_before, red_after)
    assert violet_after > violet_before + 200, (violet_before, violet_after)
    assert green_after > green_before + 50, (green_before, green_after)
