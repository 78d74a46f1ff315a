"""Files: rig parameters (TOML/JSON), point tables (CSV), atomic writes."""
