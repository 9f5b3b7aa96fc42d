"""A small robot description package written by the tests: ``testbot`` with an STL body (orange
by its URDF material), a Collada wheel (green by its own Collada material) on a continuous joint,
an OBJ mast (blue by its own .mtl), and a link whose mesh is missing; its URDF, and the messages a robot publishes (a map, TF)."""

from __future__ import annotations

import math
from pathlib import Path

ORANGE_RGBA = '0.90 0.25 0.02 1'


def box_triangles(sx: float, sy: float, sz: float, cx: float = 0.0, cy: float = 0.0, cz: float = 0.0):
    """The 12 triangles of a box centred at (cx, cy, cz), outward-facing, as vertex triples."""
    x0, x1, y0, y1, z0, z1 = cx - sx / 2, cx + sx / 2, cy - sy / 2, cy + sy / 2, cz - sz / 2, cz + sz / 2
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    faces = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4),
             (1, 2, 6), (1, 6, 5), (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]
    return v, faces


def stl(sx: float, sy: float, sz: float) -> str:
    v, faces = box_triangles(sx, sy, sz)
    out = ['solid body']
    for a, b, c in faces:
        out += ['facet normal 0 0 0', 'outer loop', *(f'vertex {v[i][0]} {v[i][1]} {v[i][2]}' for i in (a, b, c)),
                'endloop', 'endfacet']
    return '\n'.join([*out, 'endsolid body', ''])


def dae(sx: float, sy: float, sz: float, rgba: str = '0.05 0.85 0.1 1') -> str:
    """A Z-up Collada box with a material of its own colour."""
    v, faces = box_triangles(sx, sy, sz)
    positions = ' '.join(f'{c}' for p in v for c in p)
    indices = ' '.join(str(i) for f in faces for i in f)
    return f'''<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_effects><effect id="green-fx"><profile_COMMON><technique sid="common"><lambert>
    <diffuse><color>{rgba}</color></diffuse></lambert></technique></profile_COMMON></effect></library_effects>
  <library_materials><material id="green" name="green"><instance_effect url="#green-fx"/></material></library_materials>
  <library_geometries><geometry id="wheel-mesh" name="wheel"><mesh>
    <source id="wheel-pos"><float_array id="wheel-pos-array" count="{len(v) * 3}">{positions}</float_array>
      <technique_common><accessor source="#wheel-pos-array" count="{len(v)}" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="wheel-vtx"><input semantic="POSITION" source="#wheel-pos"/></vertices>
    <triangles material="green-mat" count="{len(faces)}"><input semantic="VERTEX" source="#wheel-vtx" offset="0"/>
      <p>{indices}</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="scene"><node id="wheel" name="wheel">
    <instance_geometry url="#wheel-mesh"><bind_material><technique_common>
      <instance_material symbol="green-mat" target="#green"/></technique_common></bind_material></instance_geometry>
  </node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
'''


def obj(sx: float, sy: float, sz: float) -> str:
    """A Wavefront OBJ box using material ``blue`` of ``mast.mtl``."""
    v, faces = box_triangles(sx, sy, sz)
    return '\n'.join(['mtllib mast.mtl', 'o mast', *(f'v {x} {y} {z}' for x, y, z in v), 'usemtl blue',
                      *(f'f {a + 1} {b + 1} {c + 1}' for a, b, c in faces), ''])


MTL = 'newmtl blue\nKa 0 0 0\nKd 0.05 0.15 0.95\nKs 0 0 0\nd 1\n'

URDF = f'''<?xml version="1.0"?>
<robot name="testbot">
  <material name="orange"><color rgba="{ORANGE_RGBA}"/></material>
  <link name="base_link">
    <visual><geometry><mesh filename="package://testbot/meshes/body.stl"/></geometry><material name="orange"/></visual>
  </link>
  <link name="wheel_link">
    <visual><origin xyz="0.35 0 0"/><geometry><mesh filename="package://testbot/meshes/wheel.dae"/></geometry></visual>
  </link>
  <joint name="wheel_joint" type="continuous">
    <parent link="base_link"/><child link="wheel_link"/><origin xyz="0 0 0.25"/><axis xyz="0 0 1"/>
  </joint>
  <link name="mast_link">
    <visual><geometry><mesh filename="package://testbot/meshes/mast.obj"/></geometry></visual>
  </link>
  <joint name="mast_joint" type="fixed">
    <parent link="base_link"/><child link="mast_link"/><origin xyz="0.1 0 0.15"/>
  </joint>
  <link name="ghost_link">
    <visual><geometry><mesh filename="package://testbot/meshes/missing.stl"/></geometry></visual>
    <collision><geometry><box size="0.12 0.12 0.12"/></geometry></collision>
  </link>
  <joint name="ghost_joint" type="fixed">
    <parent link="base_link"/><child link="ghost_link"/><origin xyz="-0.3 0 0.1"/>
  </joint>
</robot>
'''


def write_package(folder: Path) -> Path:
    """folder/testbot/{package.xml, meshes/body.stl, wheel.dae, mast.obj, mast.mtl, urdf/testbot.urdf}; returns folder."""
    pkg = folder / 'testbot'
    (pkg / 'meshes').mkdir(parents=True, exist_ok=True)
    (pkg / 'urdf').mkdir(exist_ok=True)
    (pkg / 'package.xml').write_text('<package format="3"><name>testbot</name></package>\n')
    (pkg / 'meshes' / 'body.stl').write_text(stl(0.4, 0.3, 0.1))
    (pkg / 'meshes' / 'wheel.dae').write_text(dae(0.3, 0.08, 0.08))
    (pkg / 'meshes' / 'mast.obj').write_text(obj(0.1, 0.1, 0.3))
    (pkg / 'meshes' / 'mast.mtl').write_text(MTL)
    (pkg / 'urdf' / 'testbot.urdf').write_text(URDF)
    return folder


def occupancy_grid(frame: str = 'map', side: int = 300, resolution: float = 0.02) -> dict:
    """A side x side map (6 m at 2 cm), origin at its centre: free floor inside a wall ring."""
    data = []
    for row in range(side):
        for col in range(side):
            edge = min(row, col, side - 1 - row, side - 1 - col)
            data.append(100 if edge < 4 else 0)
    return {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': frame},
            'info': {'map_load_time': {'sec': 0, 'nanosec': 0}, 'resolution': resolution, 'width': side,
                     'height': side, 'origin': {'position': {'x': -side * resolution / 2, 'y': -side * resolution / 2,
                                                             'z': 0.0},
                                                'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}},
            'data': data}


def transform(parent: str, child: str, x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> dict:
    return {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': parent}, 'child_frame_id': child,
            'transform': {'translation': {'x': x, 'y': y, 'z': 0.0},
                          'rotation': {'x': 0.0, 'y': 0.0, 'z': math.sin(yaw / 2), 'w': math.cos(yaw / 2)}}}


def joint_state(angle: float) -> dict:
    return {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': ''},
            'name': ['wheel_joint'], 'position': [angle], 'velocity': [], 'effort': []}
