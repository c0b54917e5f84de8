#!/usr/bin/python3
"""The "GUI" of a headless LinuxCNC instance (tests/it/linuxcnc.rs).

Reads the commands from $VOLCOMP_LINUXCNC_POSES, one per line:
  setup <MDI command>            run once, in order (e.g. M68 E3 Q1 to switch kinematics)
  pose <x> <y> <z> <a> <b> <c> <u> <v> <w>
                                 a G53 G0 move to that world position (only the letters
                                 of [TRAJ]COORDINATES are sent)
and writes to $VOLCOMP_LINUXCNC_OUT, per pose, one line
  pose <i> world <9 commanded> joints <N joint feedback> actual <9 world feedback>
(feedback = LinuxCNC's forward kinematics of the joint feedback), then "done".
Any failure is written as "error <message>" and the exit status is 1. When this
program exits, the linuxcnc script shuts the instance down.
"""
import os
import sys
import time

import linuxcnc

LETTERS = "XYZABCUVW"
TIMEOUT = 10.0


def fail(out, message):
    out.write("error %s\n" % message)
    out.flush()
    sys.exit(1)


def wait_for(out, what, predicate, stat, errors, timeout=TIMEOUT):
    end = time.monotonic() + timeout
    while True:
        stat.poll()
        if predicate(stat):
            return
        check_errors(out, errors)
        if time.monotonic() > end:
            fail(out, "timed out waiting for %s" % what)
        time.sleep(0.0005)


def check_errors(out, errors):
    e = errors.poll()
    if e:
        kind, text = e
        if kind in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
            fail(out, "LinuxCNC: %s" % text.strip().replace("\n", " "))


def main():
    ini_path = sys.argv[sys.argv.index("-ini") + 1]
    ini = linuxcnc.ini(ini_path)
    coordinates = ini.find("TRAJ", "COORDINATES").replace(" ", "").upper()
    joints = int(ini.find("KINS", "JOINTS"))
    used = sorted(set(LETTERS.index(l) for l in coordinates))
    commands = [l.split(None, 1) for l in open(os.environ["VOLCOMP_LINUXCNC_POSES"]) if l.strip()]
    out = open(os.environ["VOLCOMP_LINUXCNC_OUT"] + ".part", "w")

    stat = linuxcnc.stat()
    command = linuxcnc.command()
    errors = linuxcnc.error_channel()
    end = time.monotonic() + TIMEOUT
    while True:
        try:
            stat.poll()
            break
        except linuxcnc.error:
            if time.monotonic() > end:
                fail(out, "no status from LinuxCNC")
            time.sleep(0.01)

    command.state(linuxcnc.STATE_ESTOP_RESET)
    command.state(linuxcnc.STATE_ON)
    wait_for(out, "machine on", lambda s: s.task_state == linuxcnc.STATE_ON, stat, errors)
    command.mode(linuxcnc.MODE_MANUAL)
    command.wait_complete()
    command.home(-1)
    wait_for(out, "homing", lambda s: all(s.homed[j] for j in range(joints)), stat, errors)
    check_errors(out, errors)
    command.mode(linuxcnc.MODE_MDI)
    command.wait_complete()
    wait_for(out, "MDI mode", lambda s: s.task_mode == linuxcnc.MODE_MDI, stat, errors)

    index = 0
    for kind, rest in commands:
        if kind == "setup":
            command.mdi(rest.strip())
            if command.wait_complete(TIMEOUT) == -1:
                fail(out, "setup command timed out: %s" % rest.strip())
            check_errors(out, errors)
            wait_for(out, "setup", lambda s: s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0, stat, errors)
            continue
        target = [float(v) for v in rest.split()]
        words = " ".join("%s%.10f" % (LETTERS[k], target[k]) for k in used)
        command.mdi("G53 G0 " + words)
        # Task can report done before motion has taken the move: wait until the
        # commanded position is the target and the joint feedback has settled.
        previous = [None]

        def settled(s):
            reached = all(abs(s.position[k] - target[k]) < 1e-6 for k in used)
            snapshot = (s.joint_actual_position[:joints], s.actual_position)
            still = snapshot == previous[0]
            previous[0] = snapshot
            return reached and s.inpos and s.queue == 0 and still and \
                s.joint_actual_position[:joints] == s.joint_position[:joints]

        wait_for(out, "move to %s" % words, settled, stat, errors)
        check_errors(out, errors)
        out.write("pose %d world %s joints %s actual %s\n" % (
            index,
            " ".join(repr(v) for v in stat.position),
            " ".join(repr(v) for v in stat.joint_actual_position[:joints]),
            " ".join(repr(v) for v in stat.actual_position)))
        index += 1
    check_errors(out, errors)
    out.write("done\n")
    out.close()
    os.rename(os.environ["VOLCOMP_LINUXCNC_OUT"] + ".part", os.environ["VOLCOMP_LINUXCNC_OUT"])


if __name__ == "__main__":
    main()
