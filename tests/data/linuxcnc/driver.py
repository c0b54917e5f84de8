#!/usr/bin/python3
"""The "GUI" of a headless LinuxCNC instance (tests/it/linuxcnc.rs).

Reads the commands from $VOLCOMP_LINUXCNC_POSES, one per line:
  setup <MDI command>            run once, in order (e.g. M68 E3 Q1 to switch kinematics)
  pose <x> <y> <z> <a> <b> <c> <u> <v> <w>
                                 a G53 G0 move to that world position (only the letters
                                 of [TRAJ]COORDINATES are sent)
  feed <F> <x> <y> <z> <a> <b> <c> <u> <v> <w>
                                 the same as a G53 G1 move at feed F
and writes to $VOLCOMP_LINUXCNC_OUT, per pose, one line
  pose <i> world <9 commanded> joints <N joint feedback> actual <9 world feedback>
(feedback = LinuxCNC's forward kinematics of the joint feedback), then "done".
With $VOLCOMP_LINUXCNC_MOTOR (joint numbers, e.g. "0 1") each pose line ends with
  motor <the HAL pin joint.N.motor-pos-cmd of each, once the screw comp has settled>
(the commanded joint position plus LinuxCNC's screw compensation, read through HAL
in full precision; the joints are looped back, so the feedback equals the command).
Any failure is written as "error <message>" and the exit status is 1. When this
program exits, the linuxcnc script shuts the instance down.
"""
import os
import sys
import time

import linuxcnc

LETTERS = "XYZABCUVW"
TIMEOUT = 30.0


MESSAGES = []


def fail(out, message):
    if MESSAGES:
        message += " (LinuxCNC said: %s)" % "; ".join(MESSAGES[-3:])
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
    while True:
        e = errors.poll()
        if not e:
            return
        kind, text = e
        text = text.strip().replace("\n", " ")
        MESSAGES.append(text)
        if kind in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
            fail(out, "LinuxCNC: %s" % text)


def issue(out, command, errors, what, send):
    """Sends one command and waits until task has taken it: NML's command channel
    holds one message, so a command sent before task read the previous one would
    replace it."""
    send()
    result = command.wait_complete(TIMEOUT)
    check_errors(out, errors)
    if result == -1:
        fail(out, "%s: no answer from task" % what)
    if result == linuxcnc.RCS_ERROR:
        fail(out, "%s: refused by task" % what)


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

    issue(out, command, errors, "estop reset", lambda: command.state(linuxcnc.STATE_ESTOP_RESET))
    issue(out, command, errors, "machine on", lambda: command.state(linuxcnc.STATE_ON))
    wait_for(out, "machine on", lambda s: s.task_state == linuxcnc.STATE_ON, stat, errors)
    issue(out, command, errors, "manual mode", lambda: command.mode(linuxcnc.MODE_MANUAL))
    issue(out, command, errors, "homing", lambda: command.home(-1))
    wait_for(out, "homing", lambda s: all(s.homed[j] for j in range(joints)), stat, errors)
    issue(out, command, errors, "MDI mode", lambda: command.mode(linuxcnc.MODE_MDI))
    wait_for(out, "MDI mode", lambda s: s.task_mode == linuxcnc.MODE_MDI, stat, errors)

    motor_joints = [int(j) for j in os.environ.get("VOLCOMP_LINUXCNC_MOTOR", "").split()]
    if motor_joints:
        import hal
        component = hal.component("volcomp-driver")
        component.ready()

    def motor(words):
        """motor-pos-cmd of motor_joints once backlash-filt has reached backlash-corr
        and two reads agree."""
        end = time.monotonic() + TIMEOUT
        previous = None
        while True:
            values = [hal.get_value("joint.%d.motor-pos-cmd" % j) for j in motor_joints]
            filt = [(hal.get_value("joint.%d.backlash-filt" % j),
                     hal.get_value("joint.%d.backlash-corr" % j)) for j in motor_joints]
            if values == previous and all(f == c for f, c in filt):
                return values
            previous = values
            if time.monotonic() > end:
                fail(out, "screw compensation did not settle after %s" % words)
            time.sleep(0.005)

    index = 0
    for kind, rest in commands:
        if kind == "setup":
            issue(out, command, errors, rest.strip(), lambda: command.mdi(rest.strip()))
            wait_for(out, "setup", lambda s: s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0, stat, errors)
            continue
        target = [float(v) for v in rest.split()]
        move = "G53 G0 "
        if kind == "feed":
            move = "G53 G1 F%.6f " % target.pop(0)
        words = " ".join("%s%.10f" % (LETTERS[k], target[k]) for k in used)
        issue(out, command, errors, move + words, lambda: command.mdi(move + words))
        serial = command.serial
        # Task can report done before motion has taken the move: wait until task
        # has finished this command (the next one would be refused otherwise), the
        # commanded position is the target and the joint feedback has settled.
        previous = [None]

        def settled(s):
            if s.echo_serial_number >= serial and s.state == linuxcnc.RCS_ERROR:
                check_errors(out, errors)
                fail(out, "move refused: %s (task state %d, mode %d, interp %d, motion %d)" % (
                    words, s.task_state, s.task_mode, s.interp_state, s.motion_mode))
            done = s.echo_serial_number >= serial and s.state == linuxcnc.RCS_DONE and \
                s.interp_state == linuxcnc.INTERP_IDLE
            reached = all(abs(s.position[k] - target[k]) < 1e-6 for k in used)
            snapshot = (s.joint_actual_position[:joints], s.actual_position)
            still = snapshot == previous[0]
            previous[0] = snapshot
            return done and reached and s.inpos and s.queue == 0 and still and \
                s.joint_actual_position[:joints] == s.joint_position[:joints]

        wait_for(out, "move to %s" % words, settled, stat, errors)
        check_errors(out, errors)
        extra = ""
        if motor_joints:
            extra = " motor " + " ".join(repr(v) for v in motor(words))
        out.write("pose %d world %s joints %s actual %s%s\n" % (
            index,
            " ".join(repr(v) for v in stat.position),
            " ".join(repr(v) for v in stat.joint_actual_position[:joints]),
            " ".join(repr(v) for v in stat.actual_position),
            extra))
        index += 1
    check_errors(out, errors)
    out.write("done\n")
    out.close()
    os.rename(os.environ["VOLCOMP_LINUXCNC_OUT"] + ".part", os.environ["VOLCOMP_LINUXCNC_OUT"])


if __name__ == "__main__":
    main()
