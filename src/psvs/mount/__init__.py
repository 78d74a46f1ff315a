"""Mirror mounts: the three-point seat of each mirror (:mod:`psvs.mount.seats`) and the alignment guide
that turns a calibrated build into screw turns (:mod:`psvs.mount.guide`). docs/mount.md."""
