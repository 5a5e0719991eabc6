"""Regenerate samples/still_life.glb and samples/orbit.json (deterministic).

A small still life: a rounded vase (smooth silhouettes), a box (creases), a torus lying through
the box's top (intersection lines), a ball, on a ground slab. Several objects with node transforms
and four materials, so every line kind of the core pipeline shows up.
Run: python samples/make_sample.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent


def material(name, rgba):
    return trimesh.visual.material.PBRMaterial(name=name, baseColorFactor=rgba, metallicFactor=0.0, roughnessFactor=0.8)


def build() -> trimesh.Scene:
    scene = trimesh.Scene()
    # Vase: a surface of revolution.
    prof_z = np.linspace(0.0, 1.6, 24)
    prof_r = 0.35 + 0.22 * np.sin(prof_z * 2.4) - 0.1 * prof_z
    linestring = np.column_stack([prof_r, prof_z])
    vase = trimesh.creation.revolve(linestring, sections=48)
    vase.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    vase.visual = trimesh.visual.TextureVisuals(material=material("clay", [0.80, 0.45, 0.30, 1.0]))
    scene.add_geometry(vase, node_name="vase", geom_name="vase",
                       transform=trimesh.transformations.translation_matrix([-0.9, 0.0, -0.2]))
    box = trimesh.creation.box(extents=[0.9, 0.9, 0.9])
    box.visual = trimesh.visual.TextureVisuals(material=material("paper", [0.92, 0.90, 0.84, 1.0]))
    scene.add_geometry(box, node_name="box", geom_name="box",
                       transform=trimesh.transformations.compose_matrix(translate=[0.6, 0.45, 0.1], angles=[0, 0.5, 0]))
    torus = trimesh.creation.torus(major_radius=0.38, minor_radius=0.09, major_sections=48, minor_sections=16)
    torus.visual = trimesh.visual.TextureVisuals(material=material("brass", [0.85, 0.70, 0.25, 1.0]))
    scene.add_geometry(torus, node_name="ring", geom_name="ring",
                       transform=trimesh.transformations.compose_matrix(translate=[0.6, 0.9, 0.1], angles=[0.35, 0.5, 0]))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    ball.visual = trimesh.visual.TextureVisuals(material=material("clay", [0.80, 0.45, 0.30, 1.0]))
    scene.add_geometry(ball, node_name="ball", geom_name="ball",
                       transform=trimesh.transformations.translation_matrix([0.1, 0.3, 0.9]))
    ground = trimesh.creation.box(extents=[3.2, 0.1, 2.6])
    ground.visual = trimesh.visual.TextureVisuals(material=material("slate", [0.35, 0.38, 0.42, 1.0]))
    scene.add_geometry(ground, node_name="ground", geom_name="ground",
                       transform=trimesh.transformations.translation_matrix([0.0, -0.05, 0.2]))
    return scene


def main():
    scene = build()
    (HERE / "still_life.glb").write_bytes(scene.export(file_type="glb"))
    import sys

    sys.path.insert(0, str(HERE.parent))
    from strokekit.camera.paths import orbit_path
    from strokekit.scene.load import load_scene

    s = load_scene(HERE / "still_life.glb")
    path = orbit_path(s.center, s.radius, 24, elevation=20.0, fov_y=35.0, width=800, height=600,
                      degrees_per_frame=3.0, start_azimuth=20.0)
    (HERE / "orbit.json").write_text(json.dumps(path.to_json(), indent=1) + "\n")


if __name__ == "__main__":
    main()
