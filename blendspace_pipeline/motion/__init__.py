"""Motion: the clip model, quaternions and forward kinematics, measurement and detection of
root motion, joint names, gait, the procedural generator and the clip operations (clip_ops)."""
