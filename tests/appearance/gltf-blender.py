"""gltf-blender.py - run by Blender (blender -b --python gltf-blender.py -- FILE.gltf NV NT X Y Z):
imports FILE with Blender's own glTF importer and checks what it made: one mesh of NV
vertices (every corner its own) and NT faces, with UVs, its first vertex at (X, Y, Z) mm of
gonio's object frame in Blender's (z up too) in m, and a Principled BSDF whose base
colour is basecolor.png (sRGB), whose roughness and metallic come from
metallic_roughness.png (non-colour) and whose normal is a normal map of normal.png. Blender
3.4 has no KHR_materials_anisotropy: what it makes of the extension is printed, not checked
(the validator checks the extension). Prints 'gltf-blender: ok' when all hold; any failed
check raises (Blender exits 3 with --python-exit-code 3)."""
import sys

import bpy
import numpy

# Debian 12's Blender 3.4 importer calls numpy.bool, an alias that Debian 12's numpy 1.24 no
# longer has (AttributeError in set_poly_smoothing): the alias is put back, as numpy < 1.24 had.
if 'bool' not in vars(numpy):
    numpy.bool = bool


def upstream_image(socket):
    """The image of the Image Texture node that feeds socket (through any nodes), or None."""
    todo = [link.from_node for link in socket.links]
    while todo:
        node = todo.pop()
        if node.type == 'TEX_IMAGE':
            return node.image
        for inp in node.inputs:
            todo += [link.from_node for link in inp.links]
    return None


def main():
    path, nv, nt, *first = sys.argv[sys.argv.index('--') + 1:]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    meshes = [o for o in bpy.context.scene.objects if o.type == 'MESH']
    assert len(meshes) == 1, meshes
    me = meshes[0].data
    # gonio's object frame (z up, mm) is Blender's (z up) in m: the node's rotation to glTF's
    # y up and Blender's conversion back cancel
    world = meshes[0].matrix_world @ me.vertices[0].co
    print('gltf-blender: first vertex at', tuple(world), 'm')
    assert all(abs(world[k] - 1e-3 * float(first[k])) < 1e-7 for k in range(3)), world
    print(f'gltf-blender: {len(me.vertices)} vertices, {len(me.polygons)} faces, '
          f'{len(me.uv_layers)} uv layers')
    assert len(me.polygons) == int(nt), len(me.polygons)
    assert len(me.vertices) == int(nv), len(me.vertices)
    assert len(me.uv_layers) == 1
    mat = me.materials[0]
    bsdf = next(n for n in mat.node_tree.nodes if n.type == 'BSDF_PRINCIPLED')
    base = upstream_image(bsdf.inputs['Base Color'])
    rough = upstream_image(bsdf.inputs['Roughness'])
    metal = upstream_image(bsdf.inputs['Metallic'])
    normal = upstream_image(bsdf.inputs['Normal'])
    names = [i and i.filepath.split('/')[-1] for i in (base, rough, metal, normal)]
    print('gltf-blender: base colour, roughness, metallic, normal from', names)
    assert names == ['basecolor.png', 'metallic_roughness.png', 'metallic_roughness.png',
                     'normal.png'], names
    assert base.colorspace_settings.name == 'sRGB'
    assert rough.colorspace_settings.name == 'Non-Color'
    assert any(n.type == 'NORMAL_MAP' for n in mat.node_tree.nodes)
    print('gltf-blender: anisotropic input linked:',
          bsdf.inputs['Anisotropic'].is_linked, 'value', bsdf.inputs['Anisotropic'].default_value)
    print('gltf-blender: ok')


main()
