"""Counts test cases in JUnit XML files (gtest, pytest, rostest) under a folder.

catkin_test_results adds up the suite totals and the per-suite totals of gtest files, which
doubles the count; this counts each <testcase> once. Prints 'P F S' (passed failed skipped).
"""
import pathlib
import sys
import xml.etree.ElementTree as ET


def print_reason(element, max_lines=12):
    """The failure's message and the end of its text (the assertion), so that a CI log that
    shows only this summary still says why."""
    lines = [element.get('message') or '']
    lines += (element.text or '').strip().splitlines()[-max_lines:]
    for line in lines:
        if line.strip():
            print(f'    {line.rstrip()[:300]}', file=sys.stderr)


def count(folder):
    passed = failed = skipped = 0
    for path in sorted(pathlib.Path(folder).rglob('*.xml')):
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError:
            failed += 1  # an unreadable result file is a failure, not silence
            print(f'unreadable test result: {path}', file=sys.stderr)
            continue
        for case in root.iter('testcase'):
            problem = case.find('failure')
            if problem is None:
                problem = case.find('error')
            if problem is not None:
                failed += 1
                print(f'FAILED: {path.name}: {case.get("classname")}.{case.get("name")}',
                      file=sys.stderr)
                print_reason(problem)
            elif case.find('skipped') is not None or case.get('status') == 'notrun':
                skipped += 1
            else:
                passed += 1
    return passed, failed, skipped


if __name__ == '__main__':
    print(*count(sys.argv[1]))
