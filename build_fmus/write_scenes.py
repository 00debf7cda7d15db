"""Write every shipped scene folder of ssp/: ``python -m dsim.build_fmus.write_scenes``.

Each family of scenes has its module (the spring-mass and chain scenes in
:mod:`dsim.build_fmus.scenes`, beside the writer they all use; frames, linkages, the
four-post rig); this one lists them, so that no family module imports another.
"""
from __future__ import annotations

from pathlib import Path

from dsim.build_fmus import four_post_scenes, frame_scenes, linkage_scenes, scenes

#: every family's writer, in the order they write (each takes the root of ssp/)
WRITERS = (scenes.write_spring_mass_scenes, scenes.write_chain_scenes,
           frame_scenes.write_frame_scenes, linkage_scenes.write_all,
           four_post_scenes.write_four_post_scenes)


def write_all(root: Path = scenes.ROOT) -> None:
    """(Re)write every shipped scene folder under ``root``/ssp."""
    for write in WRITERS:
        write(root)


if __name__ == "__main__":
    write_all()
