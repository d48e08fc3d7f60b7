# SPDX-License-Identifier: GPL-3.0-or-later
"""Every skinned, animated model of Debian's assimp-testmodels that a Blender of the suite imports, played over its
whole animation as a user gets it: imported with that Blender's importer and its defaults, Volume Preservation
added with the add-on's defaults at the first frame.

- FBX/huesitos.fbx: a closed tube of 62 vertices, 11 bones of which two are FBX `_end` leaves, 40 frames.
- FBX/animation_with_skeleton.fbx: a closed, subdivided box of 1,058 vertices, 16 bones, 21 frames.
- glTF2/simple_skin/simple_skin.gltf: the glTF tutorial's skin, an open strip of 10 vertices and two joints, 133
  frames, flat: there is no volume to keep, and the skin is left exactly as skinned (3.4 and 5.2; 4.3 where its
  glTF importer runs, real_cases.enable_gltf).
- Collada/box_nested_animation.dae and Collada/library_animation_clips.dae (Blender 3.4; 4.3 and 5.2 have no
  Collada): an 8-vertex box on one bone, a 72-vertex box of open parts on five.

Collada/human.zae is refused by Blender 3.4's Collada importer (parsing errors); no Blender of the suite has more.

On every frame: the status, the shown volume within 0.5 % of the rest, and (lvp_helpers) the
core's volumes against the positions it was given and the shown mesh. With what renders have (Keep Skin Apart and
Fold-Over Prevention on), a frame opened alone gives the same bits as the frame played to, and `-c lvp_bake
--jobs 2` the same bits as `--jobs 1` and the live mesh.
"""

import os
import unittest
import zipfile

import bpy

import lvp_helpers as helpers
import real_cases
import test_bake

MODELS = os.environ.get("LVP_ASSIMP_MODELS", "/usr/share/assimp/models")
SHOWN_OFF_REST = 0.005

# (path under MODELS, importer)
CASES = {
    "huesitos": ("FBX/huesitos.fbx", "fbx"),
    "animation_with_skeleton": ("FBX/animation_with_skeleton.fbx", "fbx"),
    "simple_skin": ("glTF2/simple_skin/simple_skin.gltf", "gltf"),
    "box_nested_animation": ("Collada/box_nested_animation.dae", "collada"),
    "library_animation_clips": ("Collada/library_animation_clips.dae", "collada"),
}


def importer(kind):
    """The operator importing `kind` here, or None where this Blender has none."""
    if kind == "fbx":
        return bpy.ops.import_scene.fbx
    if kind == "gltf":
        return bpy.ops.import_scene.gltf if real_cases.enable_gltf() else None
    if kind == "collada":
        try:
            bpy.ops.wm.collada_import.get_rna_type()
        except KeyError:
            return None  # Blender 4.2 and later on Debian: built without OpenCOLLADA; 5.0 removed it
        return bpy.ops.wm.collada_import
    raise ValueError(kind)


def model_scene(name):
    """(mesh, rig, first, last) of the model imported with this Blender's importer and its defaults, Volume
    Preservation added with the add-on's defaults at the first frame of the rig's action. Raises
    unittest.SkipTest where this Blender has no importer for it (or the package is missing)."""
    relative, kind = CASES[name]
    path = os.path.join(MODELS, relative)
    if not os.path.isfile(path):
        raise unittest.SkipTest("%s is missing: apt-get install assimp-testmodels" % path)
    operator = importer(kind)
    if operator is None:
        raise unittest.SkipTest("Blender %s has no %s importer" % (bpy.app.version_string, kind))
    if operator(filepath=path) != {'FINISHED'}:
        raise RuntimeError("%s did not import" % path)
    meshes = [obj for obj in bpy.data.objects
              if obj.type == 'MESH' and any(modifier.type == 'ARMATURE' for modifier in obj.modifiers)]
    if len(meshes) != 1:
        raise RuntimeError("%s imported as %d skinned meshes" % (name, len(meshes)))
    obj = meshes[0]
    rig = next(modifier.object for modifier in obj.modifiers if modifier.type == 'ARMATURE')
    action = rig.animation_data.action if rig.animation_data else None
    if action is None:
        raise RuntimeError("%s: the rig has no action" % name)
    first, last = (int(round(frame)) for frame in action.frame_range)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = first, last
    scene.frame_set(first)
    helpers.select_only(obj)
    if bpy.ops.object.lvp_add() != {'FINISHED'}:
        raise RuntimeError("Volume Preservation could not be added to %s" % name)
    return obj, rig, first, last


class ModelTestCase(helpers.AddonTestCase):
    """One model of CASES; `plain_loss` is the least that plain skinning loses at its worst frame (the test
    would pass without the correction otherwise)."""
    name = None
    plain_loss = 0.0

    def setUp(self):
        if self.name is None:
            raise unittest.SkipTest("the base of the models' cases")
        super().setUp()
        self.obj, self.rig, self.first, self.last = model_scene(self.name)
        self.triangles = helpers.mesh_triangles(self.obj.data)
        self.rest = helpers.volume(helpers.mesh_positions(self.obj.data), self.triangles)

    def test_every_frame(self):
        scene = bpy.context.scene
        worst_plain = worst_shown = 0.0
        for frame in range(self.first, self.last + 1):
            scene.frame_set(frame)
            what = "%s, frame %d" % (self.name, frame)
            self.assertEqual(self.status_of(self.obj), ('INFO', "Correcting"), what)
            given = helpers.volume(helpers.captured_positions(self.obj), self.triangles)
            shown = helpers.volume(helpers.evaluated_positions(self.obj), self.triangles)
            if self.rest == 0.0:  # a flat strip: no volume to keep, the skin is left as skinned
                self.assertEqual(helpers.max_abs(helpers.offsets_of(self.obj)), 0.0, what)
                continue
            worst_plain = max(worst_plain, abs(given / self.rest - 1.0))
            worst_shown = max(worst_shown, abs(shown / self.rest - 1.0))
        print("    %s: frames %d-%d, plain skinning at most %.4f %% off the rest, shown %.4f %%" % (
            self.name, self.first, self.last, 100.0 * worst_plain, 100.0 * worst_shown))
        self.assertSmallerThan(worst_shown, SHOWN_OFF_REST, "%s: the shown volume against the rest" % self.name)
        self.assertGreaterEqual(worst_plain, self.plain_loss, "%s: plain skinning's worst loss" % self.name)

    def test_a_frame_is_the_same_whatever_came_before(self):
        self.obj.lvp.keep_apart = True
        self.obj.lvp.fold_over = True
        self.assertEachFrameAsOpenedAlone(self.obj, range(self.first, self.last + 1))


class ModelBakeTestCase(test_bake.CommandTestCase):
    """The model's whole animation baked headless as a farm bakes it, with the render settings (Keep Skin Apart
    on): `--jobs 2` equals `--jobs 1` and the live mesh, bit for bit."""
    name = None

    def setUp(self):
        if self.name is None:
            raise unittest.SkipTest("the base of the models' cases")
        super().setUp()

    def make_scene(self):
        obj, rig, self.first, self.last = model_scene(self.name)
        obj.lvp.keep_apart = True
        return obj, rig

    def test_jobs_2_equals_jobs_1_and_the_live_mesh(self):
        self.assertJobsEqualOneJobAndLive(self.obj, self.first, self.last)


class TestHuesitos(ModelTestCase):
    name = "huesitos"
    plain_loss = 0.1


class TestHuesitosBake(ModelBakeTestCase):
    name = "huesitos"


class TestAnimationWithSkeleton(ModelTestCase):
    name = "animation_with_skeleton"
    plain_loss = 0.01


class TestAnimationWithSkeletonBake(ModelBakeTestCase):
    name = "animation_with_skeleton"


class TestSimpleSkin(ModelTestCase):
    name = "simple_skin"


class TestSimpleSkinBake(ModelBakeTestCase):
    name = "simple_skin"


class TestBoxNestedAnimation(ModelTestCase):
    name = "box_nested_animation"


class TestBoxNestedAnimationBake(ModelBakeTestCase):
    name = "box_nested_animation"


class TestLibraryAnimationClips(ModelTestCase):
    name = "library_animation_clips"
    plain_loss = 0.03


class TestLibraryAnimationClipsBake(ModelBakeTestCase):
    name = "library_animation_clips"


if __name__ == "__main__":
    unittest.main()
