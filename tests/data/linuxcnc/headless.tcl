# A headless LinuxCNC machine for the kinematics reference test (tests/it/linuxcnc.rs):
# the kinematics module of [KINS]KINEMATICS, motion, every joint looped back
# (command = feedback), estop and tool change closed. No GUI, no vismach, no halui.
eval loadrt [lindex $::KINS(KINEMATICS) 0]
loadrt $::EMCMOT(EMCMOT) servo_period_nsec=$::EMCMOT(SERVO_PERIOD) num_joints=$::KINS(JOINTS)
addf motion-command-handler servo-thread
addf motion-controller servo-thread
for {set j 0} {$j < $::KINS(JOINTS)} {incr j} {
    net j${j}-pos joint.$j.motor-pos-cmd => joint.$j.motor-pos-fb
}
net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed
# switchable modules (xyzab_tdr_kins): the type follows M68 E3 Q<type>
if {[llength [hal list pin motion.switchkins-type]] > 0} {
    net kinstype-select motion.analog-out-03 => motion.switchkins-type
}
