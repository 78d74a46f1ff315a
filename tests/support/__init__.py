"""Test support shared by the test files (no test file imports from another; tests/test_house.py checks):

- :mod:`tests.support.cli`: run a psvs command in-process; the example rig file;
- :mod:`tests.support.browser`: the headless Chromium ``page`` fixture (a plugin of the root conftest);
- :mod:`tests.support.web`: the web tests' disc, a free port, a loopback client, the app served by uvicorn;
- :mod:`tests.support.geometry`: points over the whole field, the best rigid motion, reconstruction errors;
- :mod:`tests.support.scenes`: disc and overlap scenes, rim seeds, centroids, the paper's edge pipeline;
- :mod:`tests.support.video`: hand-held card videos, wall and disc videos, emulated camera frames;
- :mod:`tests.support.mcap`: reading MCAP recordings back;
- :mod:`tests.support.rig_draws`: rigs drawn as a user's cameras would be, random builds;
- :mod:`tests.support.sweep_scenes`: the dense sweep's scenes, scores and checks;
- :mod:`tests.support.adaptive`: adaptive-supersampling renders of the sweep;
- :mod:`tests.support.shared_files`: files shared by the test processes of one session.
"""
