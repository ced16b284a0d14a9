#!/usr/bin/env python3
"""Run every test: the pytest unit tests, then each rostest suite.

Prints one closing line ``N passed, N failed[, N skipped]`` counted from the
JUnit XML files the runners write, and exits non-zero when anything failed
or a runner broke without writing results. Run it inside ``env.bash``
(``make test`` does).
"""
import argparse
import glob
import os
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'test_results')


def junit_counts(path):
    """(passed, failed, skipped) of a JUnit XML file (pytest or rostest flavour)."""
    root = ET.parse(path).getroot()
    suites = [root] if root.tag == 'testsuite' else root.findall('testsuite')
    tests = failed = skipped = 0
    for s in suites:
        tests += int(s.get('tests', 0))
        failed += int(s.get('failures', 0)) + int(s.get('errors', 0))
        skipped += int(s.get('skipped', s.get('skip', 0)) or 0)
    return tests - failed - skipped, failed, skipped


def run_pytest():
    xml = os.path.join(RESULTS, 'pytest.xml')
    cmd = [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
           '--junitxml=' + xml, os.path.join(ROOT, 'test', 'unit')]
    print('$ ' + ' '.join(cmd), flush=True)
    rc = subprocess.call(cmd, cwd=ROOT)
    if not os.path.exists(xml):
        return 0, 1, 0, 'pytest wrote no results (exit %d)' % rc
    p, f, s = junit_counts(xml)
    if rc not in (0, 1) and f == 0:   # e.g. collection error, interrupted
        f += 1
    return p, f, s, None


def run_rostest(test_file):
    """Run one .test file; count the test cases of its test nodes (rosunit-*.xml)."""
    name = os.path.splitext(os.path.basename(test_file))[0]
    base = os.path.join(RESULTS, 'rostest', name)
    shutil.rmtree(base, ignore_errors=True)
    cmd = ['rostest', '--results-base-dir', base, '--results-filename', name + '.xml',
           'anafi_sim', os.path.basename(test_file)]
    print('$ ' + ' '.join(cmd), flush=True)
    t0 = time.time()
    rc = subprocess.call(cmd, cwd=ROOT)
    print('  (%s: exit %d, %.0f s)' % (name, rc, time.time() - t0), flush=True)
    summary = glob.glob(os.path.join(base, '*', 'rostest-*.xml'))
    cases = glob.glob(os.path.join(base, '*', 'rosunit-*.xml'))
    if not summary and not cases:
        return 0, 1, 0, '%s wrote no results (exit %d)' % (name, rc)
    p = f = s = 0
    for path in cases:
        cp, cf, cs = junit_counts(path)
        p, f, s = p + cp, f + cf, s + cs
    summary_failed = sum(junit_counts(path)[1] for path in summary)
    if (summary_failed or rc != 0) and f == 0:   # a test node died, timed out, ...
        f = 1
    if p + f + s == 0:
        return 0, 1, 0, '%s ran no test' % name
    return p, f, s, None


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--unit-only', action='store_true')
    ap.add_argument('--rostest-only', action='store_true')
    args = ap.parse_args()
    os.makedirs(RESULTS, exist_ok=True)
    totals = [0, 0, 0]
    problems = []
    steps = []
    if not args.rostest_only:
        steps.append(run_pytest)
    if not args.unit_only:
        for t in sorted(glob.glob(os.path.join(ROOT, 'test', 'ros', '*.test'))):
            steps.append(lambda t=t: run_rostest(t))
    for step in steps:
        p, f, s, problem = step()
        totals[0] += p
        totals[1] += f
        totals[2] += s
        if problem:
            problems.append(problem)
    for problem in problems:
        print('PROBLEM: ' + problem)
    line = '%d passed, %d failed' % (totals[0], totals[1])
    if totals[2]:
        line += ', %d skipped' % totals[2]
    print(line)
    return 1 if totals[1] or totals[0] == 0 else 0


if __name__ == '__main__':
    sys.exit(main())
