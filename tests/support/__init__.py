"""Test support shared by several test files: randomized rigs drawn as a user's cameras would be
(:mod:`tests.support.rig_draws`) and the scenes, files and scores of the dense sweep
(:mod:`tests.support.sweep_scenes`)."""
