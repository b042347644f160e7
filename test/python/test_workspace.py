"""The catkin workspace laid out by scripts/lib/common.sh (msm_prepare_workspace), as the tests
run in it: rosrun finds the package's tools without meeting the clone twice.

rosrun looks for an executable with `find -L` over the package folder. When the workspace's
source space (a link back to the clone) lay inside the clone's build/, every rosrun call printed
"File system loop detected" twice; the source space now lives outside the clone.
"""

import os
import subprocess


def test_rosrun_finds_a_tool_without_a_file_system_loop():
    assert 'ROS_PACKAGE_PATH' in os.environ, 'run inside the built workspace (catkin run_tests)'
    proc = subprocess.run(['rosrun', 'multisession_mapper', 'map_check', '--help'],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120,
                          universal_newlines=True, check=False)
    assert 'usage: map_check' in proc.stdout + proc.stderr, proc.stderr
    assert 'File system loop' not in proc.stderr, proc.stderr


def test_the_package_is_not_found_through_a_link_inside_the_clone():
    proc = subprocess.run(['rospack', 'find', 'multisession_mapper'], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, timeout=60, universal_newlines=True,
                          check=True)
    found = proc.stdout.strip()
    clone = os.path.realpath(os.path.join(os.path.dirname(__file__), '..', '..'))
    assert os.path.realpath(found) == clone
    # The path rosrun walks must not lie inside the clone (it would reach itself again).
    assert not os.path.abspath(found).startswith(clone + os.sep), found
