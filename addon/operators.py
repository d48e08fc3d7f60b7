# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's operators. Scripts call these ids; keep them:

    object.lvp_add            bind the selected skinned meshes and add the modifier after Armature
    object.lvp_bind           bind again after the topology changed (other changes are followed by
                              themselves, live.py; the button does the same at once)
    object.lvp_remove         remove the modifier, its node group when unused, and its attributes
    object.lvp_auto_weights   skinning weights by the paper's method (5.1) into the bones' groups

Every operator checks every selected object first and changes nothing when one of them is wrong:
it reports an ERROR that says what is wrong and how to fix it.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from . import _lvp
from . import bindings
from . import blender_api
from . import display
from . import live
from . import mesh_data
from . import names
from . import node_group
from . import offsets
from . import properties
from . import skeleton
from .session import SESSION


def _target_objects(context):
    """The selected objects, or the active one when nothing is selected."""
    objects = list(context.selected_objects)
    if not objects and context.active_object is not None:
        objects = [context.active_object]
    return objects


def _article(noun):
    return ("an " if noun[:1] in "aeiou" else "a ") + noun


def _rig_armatures(objects):
    """Armature objects that some other object of the list is deformed by (selected along with it)."""
    rigs = set()
    for obj in objects:
        if obj.type == 'MESH':
            for modifier in obj.modifiers:
                if modifier.type == 'ARMATURE' and modifier.object is not None:
                    rigs.add(modifier.object.name_full)
    return rigs


def _meshes_to_process(objects):
    """(meshes, errors): the mesh objects to work on; an armature selected with its meshes is skipped,
    any other object that is not a mesh is an error."""
    rigs = _rig_armatures(objects)
    meshes = []
    errors = []
    for obj in objects:
        if obj.type == 'MESH':
            meshes.append(obj)
        elif obj.type == 'ARMATURE' and obj.name_full in rigs:
            continue
        else:
            errors.append("%s is not a mesh (it is %s object): select the character's mesh objects "
                          "(with an Armature modifier)" % (obj.name, _article(obj.type.lower().replace("_", " "))))
    if not meshes and not errors:
        errors.append("Select the mesh objects of the character (with an Armature modifier)")
    return meshes, errors


def _editable_error(obj, modes=('OBJECT',), mesh_too=False):
    """Why obj cannot be changed by an operator, or None. The correction lives in an offsets object of
    its own (offsets.py), so a library override whose mesh stays linked can be corrected; only
    writing weights needs the mesh itself (mesh_too)."""
    if obj.library is not None:
        return ("%s is linked from a library: make a library override of it first (Object > Library Override > "
                "Make)" % obj.name)
    if mesh_too and mesh_data.is_linked(obj.data):
        return ("The mesh of %s is linked from a library, where its weights are made: change them in the library's "
                "file, or make the mesh local (Object > Relations > Make Local)" % obj.name)
    if obj.mode not in modes:
        return "%s is in %s: go back to Object Mode first" % (obj.name, obj.mode.replace("_", " ").title())
    return None


def _report_errors(operator, errors):
    operator.report({'ERROR'}, "; ".join(errors) + ". Nothing was changed.")


class _Refused(Exception):
    """Why an operator cannot change an object: then it changes none of the selected objects."""


def _plan_each(operator, context, plan, modes=('OBJECT',), mesh_too=False, discard=None):
    """The plans of plan(obj) for every selected mesh (the work an operator will do on it, checked
    before anything changes), or None with every reason reported when any of them cannot be changed:
    an operator changes all of them or none. plan raises _Refused or bindings.BindError with the
    reason; discard(plan) frees what the plans hold when they are not carried out."""
    meshes, errors = _meshes_to_process(_target_objects(context))
    plans = []
    for obj in meshes:
        try:
            problem = _editable_error(obj, modes=modes, mesh_too=mesh_too)
            if problem is not None:
                raise _Refused(problem)
            plans.append(plan(obj))
        except (_Refused, bindings.BindError) as error:
            errors.append(str(error))
    if errors:
        for each in plans if discard is not None else ():
            discard(each)
        _report_errors(operator, errors)
        return None
    return plans


class _OnSelectedMeshes:
    """An operator on the selected meshes (or the active one), in Object Mode."""

    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return context.mode == 'OBJECT' and bool(_target_objects(context))


def _tag(obj):
    obj.update_tag()
    obj.data.update_tag()


class OBJECT_OT_lvp_add(_OnSelectedMeshes, bpy.types.Operator):
    """Bind the selected skinned meshes and add a Volume Preservation modifier right after their Armature \
modifier, so they keep their volume when joints bend"""

    bl_idname = "object.lvp_add"
    bl_label = "Add Volume Preservation"

    def execute(self, context):
        def plan(obj):
            if node_group.find_modifier(obj) is not None:
                raise _Refused("%s already has a Volume Preservation modifier: use Bind to bind it again, or Remove"
                               % obj.name)
            armature_modifier, _armature_object = bindings.armature_of(obj)
            return obj, armature_modifier, bindings.bind(obj)

        plans = _plan_each(self, context, plan, discard=lambda each: each[2].close())
        if plans is None:
            return {'CANCELLED'}

        added = []

        def undo_adding():
            for obj in added:
                node_group.remove_modifier(obj)
            node_group.remove_unused_node_groups()
            for _obj, _modifier, bound in plans:
                bound.close()

        try:
            for obj, armature_modifier, bound in plans:
                node_group.add_modifier(context, obj, armature_modifier)
                added.append(obj)
        except Exception as error:
            undo_adding()
            self.report({'ERROR'}, "Could not add the modifier (%s). Nothing was changed." % error)
            return {'CANCELLED'}
        # What reaches the modifier must be the bound vertices, in order: a modifier before the
        # Armature modifier that adds vertices (Mirror, Subdivision Surface) or one after ours that
        # changes the topology would only make it pass the mesh through.
        depsgraph = context.evaluated_depsgraph_get()
        problems = []
        for obj, _armature_modifier, bound in plans:
            problem = live.evaluated_problem(obj, depsgraph, bound)
            if problem is not None:
                problems.append("%s cannot be corrected: %s" % (obj.name, problem))
        if problems:
            undo_adding()
            _report_errors(self, problems)
            return {'CANCELLED'}

        paused_only = []
        for obj, _armature_modifier, bound in plans:
            bindings.new_bind_record(obj, bound)
            offsets.new_offsets_object(obj, node_group.find_modifier(obj), bound.vertex_count)
            obj.lvp.keep_apart = bound.vertex_count <= properties.KEEP_APART_STILL_VERTICES
            obj.lvp.keep_apart_paused_only = bound.vertex_count > properties.KEEP_APART_VIEWPORT_VERTICES
            if obj.lvp.keep_apart and obj.lvp.keep_apart_paused_only:
                paused_only.append(obj.name)
            _tag(obj)
        message = "Volume Preservation added to %s" % ", ".join(obj.name for obj, _m, _b in plans)
        if paused_only:
            message += ("; Keep Skin Apart in the viewport only when paused for {} (more than {:,} vertices, where "
                        "it would slow playback)".format(", ".join(paused_only),
                                                         properties.KEEP_APART_VIEWPORT_VERTICES))
        scene = context.scene
        if scene is not None and not scene.render.use_lock_interface:
            scene.render.use_lock_interface = True
            message += "; Render > Lock Interface turned on so that F12 renders show the correction"
        self.report({'INFO'}, message)
        return {'FINISHED'}


class OBJECT_OT_lvp_bind(_OnSelectedMeshes, bpy.types.Operator):
    """Bind the selected meshes again, as needed after a topology change (others are followed by themselves)"""

    bl_idname = "object.lvp_bind"
    bl_label = "Bind"

    @classmethod
    def poll(cls, context):
        # Also in Weight Paint Mode, to bind the strokes at once rather than when painting pauses.
        return context.mode in {'OBJECT', 'PAINT_WEIGHT'} and bool(_target_objects(context))

    def execute(self, context):
        def plan(obj):
            if node_group.find_modifier(obj) is None:
                raise _Refused("%s has no Volume Preservation modifier: use Add Volume Preservation first" % obj.name)
            return obj, bindings.bind(obj)

        plans = _plan_each(self, context, plan, modes=('OBJECT', 'WEIGHT_PAINT'),
                           discard=lambda each: each[1].close())
        if plans is None:
            return {'CANCELLED'}
        for obj, bound in plans:
            node_group.repair_modifiers([obj])  # a node group deleted or edited by hand is rebuilt
            bindings.new_bind_record(obj, bound)
            if obj.lvp.display != 'NONE':
                display.update_display(obj, context)
            _tag(obj)
        self.report({'INFO'}, "Bound %s" % ", ".join(obj.name for obj, _b in plans))
        return {'FINISHED'}


def remove_from_object(obj):
    """Removes the modifier, its offsets object, the add-on's attributes and the bind record of obj (not
    its settings)."""
    for modifier in obj.modifiers:
        if node_group.is_our_modifier(modifier):
            offsets.delete_offsets_object(modifier)
    node_group.remove_modifier(obj)
    if not mesh_data.is_linked(obj.data):
        display.remove_display_attributes(obj)
        mesh = obj.data
        for name in names.ORIGINAL_MESH_ATTRIBUTES:
            attribute = mesh.attributes.get(name)
            if attribute is not None:
                mesh.attributes.remove(attribute)
    SESSION.forget(obj)
    settings = obj.lvp
    settings.bind_id = ""
    settings.topology_signature = ""
    if settings.display != 'NONE':
        settings["display"] = 0  # 'NONE' without running the update (the attributes are gone already)
    _tag(obj)


class OBJECT_OT_lvp_remove(_OnSelectedMeshes, bpy.types.Operator):
    """Remove Volume Preservation from the selected meshes: the modifier, its node group when nothing \
else uses it, and its attributes. The mesh is left exactly as it was"""

    bl_idname = "object.lvp_remove"
    bl_label = "Remove Volume Preservation"

    def execute(self, context):
        def plan(obj):
            if node_group.find_modifier(obj) is None and not obj.lvp.bind_id and not any(
                    obj.data.attributes.get(name) is not None for name in names.ORIGINAL_MESH_ATTRIBUTES):
                raise _Refused("%s has no Volume Preservation modifier: nothing to remove" % obj.name)
            return obj

        targets = _plan_each(self, context, plan)
        if targets is None:
            return {'CANCELLED'}
        for obj in targets:
            remove_from_object(obj)
        node_group.remove_unused_node_groups()
        self.report({'INFO'}, "Volume Preservation removed from %s" % ", ".join(obj.name for obj in targets))
        return {'FINISHED'}


class OBJECT_OT_lvp_auto_weights(_OnSelectedMeshes, bpy.types.Operator):
    """Compute skinning weights (bone heat, as With Automatic Weights, on any mesh; or by the distance to each \
bone) and write them into the deforming bones' vertex groups, replacing their weights"""

    bl_idname = "object.lvp_auto_weights"
    bl_label = "Volume Preservation Auto Weights"

    bones: EnumProperty(
        name="Bones",
        description="Which bones get weights; the other bones' vertex groups are left as they are",
        items=(
            ('DEFORM', "Deforming Bones", "Every bone with Deform on"),
            ('SELECTED', "Selected Bones", "The selected bones with Deform on (select them in Pose Mode): leave "
             "out the bones that are not for this mesh, such as a face's bones for a body"),
            ('COLLECTIONS', "Bone Collections", "The bones with Deform on in the bone collections named in "
             "Collections (before Blender 4.0: bone groups, or bone layers named Layer 1 to Layer 32)"),
        ),
        default='DEFORM',
    )
    collections: StringProperty(
        name="Collections",
        description="Bones: Bone Collections: the names of the bone collections whose deforming bones get weights, "
        "separated by commas",
        default="",
    )
    method: EnumProperty(
        name="Method",
        description="How the weights blend from one bone to the next",
        items=(
            ('HEAT', "Bone Heat", "Each bone's weight spreads from the skin nearest it as heat does, screened by "
             "how deep the skin lies: as Blender's With Automatic Weights, solved on any mesh (separate pieces, "
             "holes, parts that cross)"),
            ('DISTANCE', "Distance", "The paper's weights by the distance to each bone, smoothed over Blend Width "
             "times the flesh's thickness"),
        ),
        default='HEAT',
    )
    visibility: EnumProperty(
        name="Visibility Test",
        description="How a bone hidden from a vertex (behind the surface) is detected",
        items=(
            ('EXACT', "Exact", "The path to the bone is tested against the mesh, as heat weights test it"),
            ('NORMAL', "Normal", "The paper's fast test: the angle between the path to the bone and the normal "
             "(the normal then counts toward Facing Distance only as far as the triangles around agree with it)"),
        ),
        default='EXACT',
    )
    alpha: FloatProperty(
        name="Falloff",
        description="Weight = (1 / distance) ^ falloff (with Reach by Length, (bone length / distance) ^ falloff), "
        "before normalization and smoothing: high keeps each bone to its own flesh (the paper's 2 spreads a bone over its neighbours' skin, which loses volume "
        "at every bend)",
        default=16.0, min=0.1, soft_max=32.0,
    )
    by_length: BoolProperty(
        name="Reach by Length",
        description="Longer bones reach farther, as in the paper (weight = (bone length / distance) ^ falloff): "
        "where a long bone meets short ones it takes their skin (a thigh the buttock and the belly, an upper arm "
        "the shoulder). Off: each vertex goes first to its nearest bone, as with Blender's heat weights",
        default=False,
    )
    facing: BoolProperty(
        name="Facing Distance",
        description="A bone off to the side of the skin counts farther than one straight beneath it, as Blender's "
        "heat weights measure it: the skin that faces away from a bone is its flesh (the front of a hip the "
        "thigh's, not the pelvis's). Off: the straight distance, as in the paper",
        default=True,
    )
    max_influences: IntProperty(
        name="Max Influences",
        description="Keep at most this many bones per vertex (0: all, as With Automatic Weights does; 4 for "
        "game engines that take four)",
        default=0, min=0, max=32,
    )
    min_weight: FloatProperty(
        name="Min Weight",
        description="Drop weights below this, then normalize again",
        default=0.01, min=0.0, max=0.5,
    )
    blend_width: FloatProperty(
        name="Blend Width",
        description="How far the weights are smoothed along the mesh's edges, so that the skin blends between "
        "bones: times the thickness of the flesh around each bone (the middle distance of its skin from it), so "
        "a finger blends over a short distance and a hip over a long one, at any resolution (0: the paper's "
        "weights as they are)",
        default=0.9, min=0.0, max=16.0, soft_max=2.0, precision=2,
    )

    def draw(self, _context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "bones")
        if self.bones == 'COLLECTIONS':
            layout.prop(self, "collections")
        layout.prop(self, "method")
        layout.prop(self, "visibility")
        layout.prop(self, "facing")
        distance = layout.column()
        distance.active = self.method == 'DISTANCE'
        distance.prop(self, "alpha")
        distance.prop(self, "by_length")
        distance.prop(self, "blend_width")
        layout.prop(self, "max_influences")
        layout.prop(self, "min_weight")

    def execute(self, context):
        plans = _plan_each(self, context, self._weights, mesh_too=True)
        if plans is None:
            return {'CANCELLED'}
        rebound = []
        for obj, bone_names, (starts, bones, values) in plans:
            mesh_data.replace_vertex_group_weights(obj, bone_names, starts, bones, values)
            if node_group.find_modifier(obj) is not None:
                try:
                    bindings.new_bind_record(obj, bindings.bind(obj))
                    rebound.append(obj.name)
                except bindings.BindError as error:
                    self.report({'WARNING'}, "Weights written, but %s" % error)
            _tag(obj)
        message = "Weights written to %s" % ", ".join(obj.name for obj, _n, _w in plans)
        if rebound:
            message += "; bound again: %s" % ", ".join(rebound)
        self.report({'INFO'}, message)
        return {'FINISHED'}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def _weights(self, obj):
        """(obj, the deforming bones' names, the weights computed for them)."""
        _armature_modifier, armature_object = bindings.armature_of(obj)
        bone_names = [bone.name for bone in armature_object.data.bones if bone.use_deform]
        if not bone_names:
            raise _Refused("%s has no deforming bone: enable Deform on its bones" % armature_object.name)
        if self.bones == 'SELECTED':
            bone_names = [name for name in bone_names if blender_api.bone_selected(armature_object, name)]
            if not bone_names:
                raise _Refused("No deforming bone of %s is selected: select the bones to weight in Pose Mode, or "
                               "choose Bones: Deforming Bones" % armature_object.name)
        if self.bones == 'COLLECTIONS':
            bone_names = self._in_collections(armature_object, bone_names)
        if len(obj.data.polygons) == 0:
            raise _Refused("%s has no faces: automatic weights need a surface mesh" % obj.name)
        mesh = obj.data
        rest_matrices, heads, tails = skeleton.rest_skeleton_arrays(obj, armature_object, bone_names)
        positions = mesh_data.vertex_positions(mesh)
        try:
            weights = _lvp.auto_weights(
                positions, mesh_data.loop_triangles(mesh), rest_matrices, heads, tails,
                alpha=self.alpha, by_length=self.by_length, facing=self.facing, visibility=self.visibility,
                max_influences=self.max_influences, min_weight=self.min_weight,
                smoothing_thickness=self.blend_width, heat=self.method == 'HEAT', threads=bindings.thread_count())
        except (_lvp.Error, MemoryError) as error:
            raise _Refused("Cannot compute weights for %s: %s" % (obj.name, error)) from None
        return obj, bone_names, weights

    def _in_collections(self, armature_object, bone_names):
        """The names of bone_names that are in a bone collection named in self.collections."""
        wanted = [name.strip() for name in self.collections.split(",") if name.strip()]
        collections = blender_api.bone_collections(armature_object)
        known = ", ".join(sorted(collections)) or "none"
        if not wanted:
            raise _Refused("Bones: Bone Collections needs the names of bone collections in Collections (%s has: %s)"
                           % (armature_object.name, known))
        missing = [name for name in wanted if name not in collections]
        if missing:
            raise _Refused("%s has no bone collection named %s (it has: %s)"
                           % (armature_object.name, ", ".join(repr(name) for name in missing), known))
        members = set().union(*(collections[name] for name in wanted))
        chosen = [name for name in bone_names if name in members]
        if not chosen:
            raise _Refused("No deforming bone of %s is in %s: turn Deform on for their bones, or choose other "
                           "collections" % (armature_object.name, ", ".join(repr(name) for name in wanted)))
        return chosen


class OBJECT_OT_lvp_region_restriction_add(bpy.types.Operator):
    """Restrict the flesh of one region to chosen bones (e.g. the belly measured from the spine only)"""

    bl_idname = "object.lvp_region_restriction_add"
    bl_label = "Add Region Restriction"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == 'MESH'

    def execute(self, context):
        settings = context.object.lvp
        settings.region_restrictions.add()
        settings.active_region_restriction = len(settings.region_restrictions) - 1
        return {'FINISHED'}


class OBJECT_OT_lvp_region_restriction_remove(bpy.types.Operator):
    """Remove the selected region restriction"""

    bl_idname = "object.lvp_region_restriction_remove"
    bl_label = "Remove Region Restriction"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == 'MESH' and len(obj.lvp.region_restrictions) > 0

    def execute(self, context):
        obj = context.object
        settings = obj.lvp
        index = min(settings.active_region_restriction, len(settings.region_restrictions) - 1)
        settings.region_restrictions.remove(index)
        settings.active_region_restriction = max(0, index - 1)
        SESSION.changes.expect_own_update(obj)
        obj.update_tag()
        return {'FINISHED'}


classes = (
    OBJECT_OT_lvp_add,
    OBJECT_OT_lvp_bind,
    OBJECT_OT_lvp_remove,
    OBJECT_OT_lvp_auto_weights,
    OBJECT_OT_lvp_region_restriction_add,
    OBJECT_OT_lvp_region_restriction_remove,
)


register, unregister = bpy.utils.register_classes_factory(classes)
