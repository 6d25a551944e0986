"""Tests of urdf_pipeline/live: live views from a control loop and from a robot's stream."""
