"""Planning: fold recipes → fold actions → end-effector waypoints. Never imports the simulator."""
