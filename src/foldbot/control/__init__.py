"""Control: IK along Cartesian paths, time parametrisation, joint and gripper execution, monitors."""
