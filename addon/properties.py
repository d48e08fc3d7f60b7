# SPDX-License-Identifier: GPL-3.0-or-later
"""Per-object settings, Object.lvp: what the artist chooses, and the bind record saved in the file.
All of them can be overridden on a character linked into a shot (library override).

Changing a setting tags the object, so the handlers correct it again with the new setting (the map
is replaced in place, or the object is rebound when the effect switches between local and global).
"""

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, IntProperty,
                       PointerProperty, StringProperty)

from . import display
from .session import SESSION

# Every setting can be changed on a library override (a character linked into a shot) and is kept
# in the shot's file; otherwise Blender would give it back the character file's value on reopening.
OVERRIDABLE = {'LIBRARY_OVERRIDABLE'}


def _own_property_changed(settings, context):
    """Blender tags the whole object when an add-on's property of it changes, and reports its mesh as
    changed: not a change of its weights or rest mesh, which are not read again for it."""
    obj = settings.id_data
    if isinstance(obj, bpy.types.Object):
        SESSION.changes.expect_own_update(obj)


def _settings_changed(settings, context):
    obj = settings.id_data
    if isinstance(obj, bpy.types.Object):
        _own_property_changed(settings, context)
        # The handlers correct the object again with the new setting.
        obj.update_tag(refresh={'OBJECT'})


def _setting(kind, **options):
    """A setting of the correction (kind: FloatProperty...): overridable, and changing it has the object
    corrected again with it."""
    return kind(override=OVERRIDABLE, update=_settings_changed, **options)


def _display_changed(settings, context):
    obj = settings.id_data
    if isinstance(obj, bpy.types.Object):
        _own_property_changed(settings, context)
        display.update_display(obj, context)


EFFECT_ITEMS = (
    ('ORGANIC', "Organic",
     "Flesh: volume goes back near bending joints, more where the flesh is far from the bone "
     "(paper eq. 7, per region)"),
    ('RUBBER', "Rubber", "Rubber toys: a radial bulge at bending joints (paper 4.2, per region)"),
    ('PAINTED', "Painted", "Where the volume goes is painted in a vertex group (per region)"),
    ('GLOBAL', "Global",
     "One region, the whole closed mesh: its total volume is kept (paper 3.2-3.3, organic map)"),
)

# Add turns Keep Skin Apart on in the viewport, so that the viewport shows what renders. On meshes this small (game
# characters, low-poly rigs) it costs two to three times the correction, a few milliseconds a frame, and stays on
# while the animation plays. Denser meshes have it only on a still frame (keep_apart_paused_only): on the
# 7,500-vertex hand of the tests it is about six times the frame (BENCHMARKS.md), which posing or scrubbing one frame
# affords and playback at the scene's frame rate does not.
KEEP_APART_VIEWPORT_VERTICES = 3000
# Beyond this many vertices Add leaves it off in the viewport: each update while posing would take more than about
# 35 ms on two cores (1.6-1.9 microseconds a vertex on the hand and on the 24k Rigify human, BENCHMARKS.md).
KEEP_APART_STILL_VERTICES = 20000

RESTORE_ITEMS = (
    ('WHOLE_MESH', "Whole Mesh",
     "The lost volume goes back where joints bend, with one strength for the whole mesh (each separate "
     "piece): smooth where joints bend hard; a region (a bone's skin) is not restored on its own"),
    ('EACH_REGION', "Each Region",
     "Every region (a bone's skin) back to its own rest volume (paper 5.3); where joints bend hard, "
     "neighbouring regions can pull against each other (bulges beside dents)"),
)

DISPLAY_ITEMS = (
    ('NONE', "None", "No colour display"),
    ('SEGMENTATION', "Segmentation",
     "Colour each vertex by its region, the bone with its largest weight (paper Fig. 1b)"),
    ('CORRECTION_MAP', "Correction Map",
     "Colour each vertex by how much it may move, from blue (rigid) to red (moves most) (paper Fig. 8)"),
)


class LVP_PG_region_restriction(bpy.types.PropertyGroup):
    """Restricts the distance term of one region's map to chosen bones (paper Fig. 11)."""

    region: _setting(
        StringProperty,
        name="Region",
        description="Deforming bone whose region is restricted",
    )
    bones: _setting(
        StringProperty,
        name="Bones",
        description="Comma-separated bone names: the region's flesh is measured from these bones only "
                    "(e.g. the belly from the spine)",
    )


class LVP_PG_settings(bpy.types.PropertyGroup):
    """Local Volume Preservation settings of one object."""

    effect: _setting(
        EnumProperty,
        name="Effect",
        description="How the lost volume is put back",
        items=EFFECT_ITEMS,
        default='ORGANIC',
    )
    alpha: _setting(
        FloatProperty,
        name="Alpha",
        description="Concentration at the joints: higher keeps the correction closer to where no bone "
                    "dominates",
        default=1.0, min=0.0, soft_max=4.0,
    )
    beta: _setting(
        FloatProperty,
        name="Beta",
        description="Dependence on the distance to the bones: higher moves flesh far from the bone more "
                    "than flesh over it",
        default=1.0, min=0.0, soft_max=4.0,
    )
    restore: _setting(
        EnumProperty,
        name="Restore",
        description="What each frame brings back to its rest volume",
        items=RESTORE_ITEMS,
        default='WHOLE_MESH',
    )
    bulge_width: _setting(
        FloatProperty,
        name="Bulge Width",
        description="How far the restored volume spreads around a bending joint, in multiples of the "
                    "flesh's thickness there (its distance to the bone); 0 keeps it to the band where the "
                    "weights blend, as the paper does. Not used where the Armature modifier has a Vertex Group",
        default=1.0, min=0.0, max=8.0, soft_max=3.0,
    )
    smoothing: _setting(
        IntProperty,
        name="Smoothing",
        description="Passes smoothing the correction over the surface, so that offsets along normals that turn "
                    "fast (a folding knuckle, the palm of a closing hand) open no creases; the volume is restored "
                    "after them. 0 keeps the paper's offsets",
        default=6, min=0, max=64, soft_max=16,
    )
    iterations: _setting(
        IntProperty,
        name="Iterations",
        description="Correction passes per frame; 1 is the paper's single pass, more removes its "
                    "linearization error",
        default=8, min=1, max=64,
    )
    tolerance: _setting(
        FloatProperty,
        name="Tolerance",
        description="The passes stop once every region is this close to its rest volume (percent of the "
                    "region's volume); larger saves passes and leaves more of the error",
        subtype='PERCENTAGE',
        default=0.01, min=0.001, max=10.0, soft_max=1.0, precision=3, step=1,
    )
    fold_over: _setting(
        BoolProperty,
        name="Fold-Over Prevention",
        description="Keep the skin of a bending joint from folding through itself; squeezed flesh bulges "
                    "instead (paper 5.4)",
        default=False,
    )
    keep_apart: _setting(
        BoolProperty,
        name="Keep Skin Apart in the Viewport",
        description="Never push skin through skin while animating: where the correction would make two parts of "
                    "the surface cross that plain skinning keeps apart, it is shortened there and the volume goes "
                    "elsewhere. Several times slower than the correction alone: Add turns it on for meshes of up to "
                    "%d vertices, above %d only for still frames (Only When Paused)"
                    % (KEEP_APART_STILL_VERTICES, KEEP_APART_VIEWPORT_VERTICES),
        default=False,
    )
    keep_apart_paused_only: _setting(
        BoolProperty,
        name="Keep Skin Apart Only When Paused",
        description="In the viewport, keep skin apart on a still frame (posing, scrubbing, a stopped animation) "
                    "but not while the animation plays, where its cost would lower the frame rate. Add turns this "
                    "on for meshes of more than %d vertices" % KEEP_APART_VIEWPORT_VERTICES,
        default=False,
    )
    keep_apart_render: _setting(
        BoolProperty,
        name="Keep Skin Apart in Renders",
        description="Never push skin through skin in renders and in Bake to PC2: where the correction would make "
                    "two parts of the surface cross that plain skinning keeps apart, it is shortened there and the "
                    "volume goes elsewhere",
        default=True,
    )
    painted_vertex_group: _setting(
        StringProperty,
        name="Painted Map",
        description="Vertex group whose weights say where the volume goes (Painted effect)",
    )
    region_restrictions: CollectionProperty(
        override={'LIBRARY_OVERRIDABLE', 'USE_INSERTION'},
        type=LVP_PG_region_restriction,
        name="Region Restrictions",
        description="Regions whose flesh is measured from chosen bones only",
    )
    active_region_restriction: IntProperty(name="Active Region Restriction", default=0, min=0, override=OVERRIDABLE,
                                           update=_own_property_changed)
    display: EnumProperty(
        override=OVERRIDABLE,
        name="Display",
        description="Show the segmentation or the correction map as a colour attribute in the viewport "
                    "(Solid shading, Color: Attribute)",
        items=DISPLAY_ITEMS,
        default='NONE',
        update=_display_changed,
    )

    # The bind record, written by the operators and saved with the file. The binding itself lives in
    # memory and is rebuilt from the mesh after a file load; the signature tells whether that is
    # still possible (same topology) or whether the artist must bind again.
    bind_id: StringProperty(name="Bind Id", description="Identifies the last bind", options={'HIDDEN'},
                            override=OVERRIDABLE)
    topology_signature: StringProperty(
        override=OVERRIDABLE,
        name="Topology Signature", description="Topology of the mesh at the last bind", options={'HIDDEN'})
    bind_rule: IntProperty(
        override=OVERRIDABLE,
        name="Bind Rule", description="The rule the last bind was made by (bindings.BIND_RULE; 0: before the rules "
                                      "were numbered)", options={'HIDDEN'}, default=0, min=0)
    previous_color_attribute: StringProperty(
        override=OVERRIDABLE,
        name="Previous Colour Attribute",
        description="Active colour attribute before the display was turned on (restored when it is turned off)",
        options={'HIDDEN'})


classes = (
    LVP_PG_region_restriction,
    LVP_PG_settings,
)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    bpy.types.Object.lvp = PointerProperty(type=LVP_PG_settings, name="Local Volume Preservation",
                                           override=OVERRIDABLE)


def unregister():
    del bpy.types.Object.lvp
    _unregister_classes()
