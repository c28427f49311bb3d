"""Run a command and record its peak memory: `python launch.py REPORT CMD...`.

Linux carries a process's RSS high-water mark across fork and exec, so a
child started by a large parent reports at least the parent's size. This
launcher is small (the bare interpreter, no imports beyond the standard
library), so the peak it reads for its child (os.wait4's ru_maxrss) is the
child's own. It writes {"status": exit status, "maxrss_mb": ..., "cpu_s":
user + system seconds} to REPORT.
"""

import json
import os
import sys


def main() -> int:
    report, cmd = sys.argv[1], sys.argv[2:]
    pid = os.fork()
    if pid == 0:
        try:
            os.execvp(cmd[0], cmd)
        finally:
            os._exit(127)
    _, status, usage = os.wait4(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    with open(report, "w") as f:
        json.dump({"status": code, "maxrss_mb": usage.ru_maxrss / 1024,
                   "cpu_s": usage.ru_utime + usage.ru_stime}, f)
    return code if code >= 0 else 128 - code


if __name__ == "__main__":
    raise SystemExit(main())
