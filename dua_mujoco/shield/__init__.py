"""The safety shield: between a controller and ``mj_step``, it lets through only motions it can
still stop before anything protected may reach the robot (issue 40). Today: its failsafe."""
