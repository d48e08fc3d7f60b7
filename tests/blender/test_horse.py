# SPDX-License-Identifier: GPL-3.0-or-later
"""A real animated game asset: the horse of tests/data/horse (CC0; 2,146 vertices split at seams, 1,709 points, one
closed surface, 56 bones of which 51 carry weights, 14 actions), imported with Blender's glTF importer and its
defaults, Volume Preservation added with the add-on's defaults, every frame of every action played:

- the shown volume within 0.5 % of the rest at every frame (plain skinning loses up to 12.5 %, Eating), and the
  panel says "Correcting";
- what the core reports is what was shown: its volume before the correction is the volume of the positions it was
  given (the Armature modifier's, read from the modifier's captured attribute), its volume after the volume of the
  evaluated mesh, each to 1e-6;
- a frame's correction is the same bits whatever was evaluated before it (played to, or opened at, as the first
  frame of a farm's chunk is), with what renders have: Keep Skin Apart, and Fold-Over Prevention too. The core
  keeps per-frame state between calls (Keep Skin Apart's shares of skin that does not move this frame, contact.c;
  which skin moves rigidly, frame_map.c), and none of it may carry from one frame to the next.

The clips' scale keys are 1 to about 1e-5 (the exporter's rounding): the bones are stretched against each other by
up to 2e-5 in every frame. Taken for squash and stretch, that would give up restoring the whole mesh (a third to a
half of the loss left on whole actions) while the panel says "Correcting"; a stretch that changes no region's
volume by more than the tolerance is none (lvp.h, RESTORE).
"""

import os
import unittest

import bpy

import lvp_helpers as helpers
import real_cases
import surface_quality as quality
import test_bake

HORSE = os.path.join(helpers.REPO, "tests", "data", "horse", "horse-animations.glb")
ACTIONS = 14
SHOWN_OFF_REST = 0.005


def horse_scene(low_poly=None):
    """(mesh, rig) of the horse imported by Blender's glTF importer, Volume Preservation added with the add-on's
    defaults; each action is played alone, as an animator plays it (the importer puts the others in NLA tracks,
    muted here). low_poly: first made a level of detail of that ratio of its faces, as an artist makes one in
    Blender: Merge by Distance (the seams joined), then the Decimate modifier applied under the Armature modifier
    (the weights interpolated). Raises unittest.SkipTest where this Blender cannot import glTF."""
    if not real_cases.enable_gltf():
        raise unittest.SkipTest("this Blender cannot import glTF here (real_cases.enable_gltf)")
    bpy.ops.import_scene.gltf(filepath=HORSE)
    meshes = [obj for obj in bpy.data.objects
              if obj.type == 'MESH' and any(modifier.type == 'ARMATURE' for modifier in obj.modifiers)]
    if len(meshes) != 1:
        raise RuntimeError("the horse imported as %d skinned meshes" % len(meshes))
    obj = meshes[0]
    rig = next(modifier.object for modifier in obj.modifiers if modifier.type == 'ARMATURE')
    for track in rig.animation_data.nla_tracks:
        track.mute = True
    helpers.select_only(obj)
    if low_poly is not None:
        _decimate(obj, low_poly)
    if bpy.ops.object.lvp_add() != {'FINISHED'}:
        raise RuntimeError("Volume Preservation could not be added to the horse")
    return obj, rig


def _decimate(obj, ratio):
    """Merge by Distance, then the Decimate modifier (collapse, `ratio` of the faces) applied to obj's mesh alone."""
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.select_all(action='SELECT')
    bpy.ops.mesh.remove_doubles(threshold=1e-6)
    bpy.ops.object.mode_set(mode='OBJECT')
    armature = next(modifier for modifier in obj.modifiers if modifier.type == 'ARMATURE')
    armature.show_viewport = False
    decimate = obj.modifiers.new("Decimate", 'DECIMATE')
    decimate.ratio = ratio
    bpy.ops.object.modifier_move_to_index(modifier=decimate.name, index=0)
    bpy.ops.object.modifier_apply(modifier=decimate.name)
    armature.show_viewport = True


def play(rig, name):
    """Makes the action whose name starts with `name` the rig's; returns its (first, last) frame."""
    action = next(action for action in bpy.data.actions if action.name.startswith(name))
    rig.animation_data.action = action
    return tuple(int(round(frame)) for frame in action.frame_range)


class TestHorse(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        self.obj, self.rig = horse_scene()
        self.triangles = helpers.mesh_triangles(self.obj.data)
        self.rest = helpers.volume(helpers.mesh_positions(self.obj.data), self.triangles)

    def test_every_frame_of_every_action(self):
        actions = sorted(bpy.data.actions, key=lambda action: action.name)
        self.assertEqual(len(actions), ACTIONS, [action.name for action in actions])
        scene = bpy.context.scene
        worst_plain = 0.0
        for action in actions:
            self.rig.animation_data.action = action
            first, last = (int(round(frame)) for frame in action.frame_range)
            worst_shown = 0.0
            for frame in range(first, last + 1):
                scene.frame_set(frame)
                what = "%s, frame %d" % (action.name, frame)
                level, status = self.status_of(self.obj)
                self.assertEqual((level, status), ('INFO', "Correcting"), what)
                stats = self.addon.session.SESSION.bound(self.obj).stats
                given = helpers.volume(helpers.captured_positions(self.obj), self.triangles)
                shown = helpers.volume(helpers.evaluated_positions(self.obj), self.triangles)
                self.assertSmallerThan(abs(stats["volume_before"] / given - 1.0), 1e-6,
                                       "%s: the core's volume before against the positions it was given" % what)
                self.assertSmallerThan(abs(stats["volume_after"] / shown - 1.0), 1e-6,
                                       "%s: the core's volume after against the shown mesh" % what)
                worst_plain = max(worst_plain, abs(given / self.rest - 1.0))
                worst_shown = max(worst_shown, abs(shown / self.rest - 1.0))
            print("    %-22s shown within %.4f %% of the rest" % (action.name, 100.0 * worst_shown))
            self.assertSmallerThan(worst_shown, SHOWN_OFF_REST, "%s: the shown volume" % action.name)
        self.assertGreater(worst_plain, 0.1, "plain skinning loses volume in these actions")

    def test_a_frame_is_the_same_whatever_came_before(self):
        first, last = play(self.rig, "Walk")
        self.obj.lvp.keep_apart = True
        self.obj.lvp.fold_over = True
        played = self.assertEachFrameAsOpenedAlone(self.obj, range(first, last + 1))
        self.assertGreater(max(map(abs, played[last])), 0.0)


class HorseSurfaceMeasures:
    """The horse's surface over every frame of its actions, by the measures of ../shared/QUALITY.md against plain
    skinning at the same frame (mixed into the test cases below)."""

    # No vertex further out of its neighbours' surface than plain skinning leaves it by more than this share of the
    # largest offset (surface_quality.shard), as the roughness.
    SHARD_OF_LARGEST = 0.25

    def surface_of_every_action(self, obj, rig, only=None):
        """{action name: ((largest new contacts, largest added crossings), largest creases added, largest
        roughness over the largest offset)} over every frame of each action (or of those whose names start
        with `only`), each frame's status checked; and self.shards, {action name: the largest shard over the
        largest offset} (surface_quality.shard)."""
        mesh = quality.WeldedMesh(helpers.mesh_positions(obj.data), helpers.mesh_triangles(obj.data))
        self.creases_allowed = len(mesh.interior_edges()) / quality.EDGES_PER_CREASE
        scene = bpy.context.scene
        result = {}
        self.shards = {}
        for action in sorted(bpy.data.actions, key=lambda action: action.name):
            if only and not action.name.startswith(only):
                continue
            rig.animation_data.action = action
            first, last = (int(round(frame)) for frame in action.frame_range)
            new_contacts = creases = 0
            added = []  # per frame
            rough = shard = 0.0
            for frame in range(first, last + 1):
                scene.frame_set(frame)
                self.assertEqual(self.status_of(obj), ('INFO', "Correcting"), "%s, frame %d" % (action.name, frame))
                measured = quality.measure_pose(mesh, helpers.uncorrected_positions(obj),
                                                {"vp": helpers.evaluated_positions(obj)})
                shown = measured["vp"]
                new_contacts = max(new_contacts, shown["new contacts"])
                added.append(shown["added crossings"])
                creases = max(creases, shown["creases"])
                if shown["largest_offset"] > 0.0:
                    rough = max(rough, shown["roughness"] / shown["largest_offset"])
                    shard = max(shard, shown["shard"] / shown["largest_offset"])
            print("    %-22s new contacts %d, crossing pairs at most %+d against plain skinning, creases added %d "
                  "(%.1f allowed), roughness %.2f and shard %.2f of the largest offset"
                  % (action.name, new_contacts, max(added), creases, self.creases_allowed, rough, shard))
            result[action.name] = ((new_contacts, max(added)), creases, rough)
            self.shards[action.name] = shard
        return result

    def assertNoShard(self):
        """No action of the last surface_of_every_action with a shard past SHARD_OF_LARGEST."""
        for name, shard in self.shards.items():
            self.assertLessEqual(shard, self.SHARD_OF_LARGEST, "%s: a shard against the largest offset" % name)


class TestHorseSurface(HorseSurfaceMeasures, helpers.AddonTestCase):
    """The horse's surface, every frame of every action, by the measures of ../shared/QUALITY.md against plain
    skinning at the same frame: creases added at most one per 300 edges, and roughness against the largest
    offset; with what renders have (Keep Skin Apart on), no more crossing pairs than plain skinning and no new
    contact (surface_quality.measure_pose: "added crossings", "new contacts"). Keep Skin Apart never leaves a
    frame out: by a rule that gave up past one triangle in 20 crossing anew, lay_to_idle had 56 crossing pairs
    more than plain skinning on 5 frames."""

    def test_every_frame_of_every_action(self):
        """With the add-on's defaults (the viewport's), roughness at most a quarter of the largest offset, as
        QUALITY.md asks, on every frame. On this coarse mesh (flesh an edge or two thick) roughness comes easily:
        where the map peaks (a vertex whose weights differ from its neighbours'), where the weights' band is
        narrow, and where a vertex whose strongest bones move together lies inside moving skin."""
        obj, rig = horse_scene()
        for name, (_crossings, creases, rough) in self.surface_of_every_action(obj, rig).items():
            self.assertLessEqual(creases, self.creases_allowed, "%s: creases added" % name)
            self.assertLessEqual(rough, 0.25, "%s: roughness against the largest offset" % name)
        self.assertNoShard()

    def test_every_frame_of_every_action_with_keep_skin_apart(self):
        """Keeping skin apart, the correction fades where the skin comes near other skin (the tail on the rump in
        lay_to_idle, a leg folding against the belly), over the rings around, and the crossing test shortens what
        the fade leaves, smoothed the same way, as QUALITY.md asks: roughness at most a quarter of the largest
        offset. Where plain skinning already pushes one skin into another (a front leg into the ribcage in
        Turn_Left), any offset pushes it further, the crossing test leaves a vertex none, and its neighbours may
        keep only a little more; the smoothing of the shares never raises a share its pairs lowered, or the test
        would hold that vertex back once more, alone."""
        obj, rig = horse_scene()
        obj.lvp.keep_apart = True
        for name, ((new_contacts, added), creases, rough) in self.surface_of_every_action(obj, rig).items():
            self.assertEqual(new_contacts, 0, "%s: skin meeting skin that plain skinning keeps apart" % name)
            self.assertLessEqual(added, 0, "%s: more crossing pairs than plain skinning" % name)
            self.assertLessEqual(creases, self.creases_allowed, "%s: creases added" % name)
            self.assertLessEqual(rough, 0.25, "%s: roughness against the largest offset" % name)
        self.assertNoShard()


class TestHorseFoldOverSurface(HorseSurfaceMeasures, helpers.AddonTestCase):
    """The horse's surface with Fold-Over and Keep Skin Apart."""

    def test_fold_over_kick_stands_no_patch_out(self):
        """Fold-Over with Keep Skin Apart, the hind legs kicking: fold-over holds the skin between them on a
        hip's contact plane, where plain skinning crosses, and the crossing test shortens the skin around it
        (it would meet the other leg's). That patch comes down with its neighbours as far as it can without
        the skinning's crossing coming back; raised whole instead, it stood out of them (roughness 0.65 of the
        largest offset, shard 0.20). Measured on 3.4: 0.34 and 0.10; the quarter QUALITY.md asks is not reached
        with Fold-Over on this horse yet, hence the looser bound. The 0.34 is on the flank, where no skin meets:
        the plane of the pelvis turning against the barrel it lies in (siblings under the hips bone) runs through
        the flank, and half the pelvis's bend carries it across skin 0.5 from the joint (BENCHMARKS.md, Fold-Over
        on the horse's kick)."""
        obj, rig = horse_scene()
        obj.lvp.keep_apart = True
        obj.lvp.fold_over = True
        for name, ((_new_contacts, added), creases, rough) in self.surface_of_every_action(obj, rig, "Kick").items():
            self.assertLessEqual(added, 0, "%s: more crossing pairs than plain skinning" % name)
            self.assertLessEqual(creases, self.creases_allowed, "%s: creases added" % name)
            self.assertLessEqual(rough, 0.4, "%s: roughness against the largest offset" % name)
        self.assertNoShard()

    def test_fold_over_crosses_no_more_pairs_than_plain_skinning(self):
        """Fold-Over with Keep Skin Apart, every frame of every action: no more crossing pairs than plain skinning.
        Falling (Death), fold-over presses two sheets of skin at the hip onto its contact plane where plain
        skinning crosses them, and the press leaves that crossing as it was and crosses more pairs around it.
        Skin that fold-over holds is kept in place only where the press parted a crossing of the skinning;
        kept wherever the skinning crossed, those sheets could not be moved back: 16 pairs where plain skinning
        has 4, 5 of them new contacts (frame 20). Measured on 3.4: every action at or below plain skinning's."""
        obj, rig = horse_scene()
        obj.lvp.keep_apart = True
        obj.lvp.fold_over = True
        for name, ((_new_contacts, added), _creases, _rough) in self.surface_of_every_action(obj, rig).items():
            self.assertLessEqual(added, 0, "%s: more crossing pairs than plain skinning" % name)


class TestLowPolyHorseSurface(TestHorseSurface):
    """The horse as a low-poly game animal (issue 46: 300 to 3,000 points, walking and running): a level of detail
    of 0.18 of its faces (horse_scene's low_poly: about 300 points and 600 triangles, edges up to several times
    the mean), with Smoothing 10, what README tells users of coarse meshes. With Keep Skin Apart (renders), every
    frame of every action: no new contact and no more crossing pairs than plain skinning (Keep Skin Apart once
    left out frames of a running animal this coarse where more than one triangle in 20 would cross anew), and at
    most one crease added per 300 edges (3.1 allowed: 2 at most on 3.4, 3 on lay_to_idle on 5.2, whose importer
    and Decimate give a slightly different mesh).

    Roughness is held to COARSE_ROUGHNESS of the largest offset, QUALITY.md's quarter: on every frame of every action,
    with the defaults and with Keep Skin Apart, 0.14-0.23 on 3.4 and 0.15-0.24 on 5.2, close to it because on a mesh
    this coarse the measure reads its normals as much as the correction (an even inflation reads 0.27-0.34 at the
    90th percentile of the vertices of 600-point bodies; BENCHMARKS.md, Roughness on bodies of 600 points), the more
    where the whole correction is small. It was held to 0.3 while lay_to_idle read 0.29 (the offsets each fade left
    restored unsmoothed, at its frame 20, the top of a bulge four edges across on the rump), 5.2's mesh up to 0.50 (one
    vertex that a bone's line passes through left still among skin that moves; map.c, lvp__fill_map_pits) and
    Turn_Left 0.27 (before the smoothing feathered the rim of the moving skin, offset_smoothing.c).
    Measured on 3.4 and 5.2 (4.3's chroot cannot import glTF)."""

    LOW_POLY = 0.18
    SMOOTHING = 10
    COARSE_ROUGHNESS = quality.ROUGHNESS_OF_LARGEST
    # The shard reads the offsets' roughness along the normals, which turn by tens of degrees from vertex to vertex
    # here: 0.10-0.22 on every action with Keep Skin Apart (3.4 and 5.2; 0.29 on lay_to_idle before the offsets each
    # fade left were smoothed), at the vertex the roughness finds.
    SHARD_OF_LARGEST = COARSE_ROUGHNESS

    def low_poly_scene(self):
        obj, rig = horse_scene(low_poly=self.LOW_POLY)
        self.assertTrue(250 <= len(obj.data.vertices) <= 400, len(obj.data.vertices))
        self.assertEqual(real_cases.open_edge_count(obj.data), 0)
        obj.lvp.smoothing = self.SMOOTHING
        return obj, rig

    def test_every_frame_of_every_action(self):
        obj, rig = self.low_poly_scene()
        for name, (_crossings, _creases, rough) in self.surface_of_every_action(obj, rig).items():
            self.assertLessEqual(rough, self.COARSE_ROUGHNESS, "%s: roughness against the largest offset" % name)
        self.assertNoShard()

    def test_every_frame_of_every_action_with_keep_skin_apart(self):
        obj, rig = self.low_poly_scene()
        obj.lvp.keep_apart = True
        for name, ((new_contacts, added), creases, rough) in self.surface_of_every_action(obj, rig).items():
            self.assertEqual(new_contacts, 0, "%s: skin meeting skin that plain skinning keeps apart" % name)
            self.assertLessEqual(added, 0, "%s: more crossing pairs than plain skinning" % name)
            self.assertLessEqual(creases, self.creases_allowed, "%s: creases added" % name)
            self.assertLessEqual(rough, self.COARSE_ROUGHNESS, "%s: roughness against the largest offset" % name)
        self.assertNoShard()


class TestHorseBake(test_bake.CommandTestCase):
    """The horse's Walk baked headless as a farm bakes it: `--jobs 2` (the second slice starts at frame 12) equals
    `--jobs 1` and the live mesh, bit for bit, with the render settings (Keep Skin Apart on). Before a frame's
    correction stopped depending on the frames before it, frame 12 differed by 2.9e-4."""

    def make_scene(self):
        obj, rig = horse_scene()
        scene = bpy.context.scene
        scene.frame_start, scene.frame_end = 1, play(rig, "Walk")[1]
        scene.frame_set(1)
        obj.lvp.keep_apart = True  # the live mesh as renders and bakes correct it
        return obj, rig

    def test_jobs_2_equals_jobs_1_and_the_live_mesh(self):
        self.assertJobsEqualOneJobAndLive(self.obj, 1, bpy.context.scene.frame_end)


if __name__ == "__main__":
    unittest.main()
