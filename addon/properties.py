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

DISPLAY_ITEMS = (
    ('NONE', "None", "No colour display"),
    ('SEGMENTATION', "Segmentation",
     "Colour each vertex by its region, the bone with its largest weight (paper Fig. 1b)"),
    ('CORRECTION_MAP', "Correction Map",
     "Colour each vertex by how much it may move, from blue (rigid) to red (moves most) (paper Fig. 8)"),
)


class LVP_PG_region_restriction(bpy.types.PropertyGroup):
    """Restricts the distance term of one region's map to chosen bones (paper Fig. 11)."""

    region: StringProperty(
        override=OVERRIDABLE,
        name="Region",
        description="Deforming bone whose region is restricted",
        update=_settings_changed,
    )
    bones: StringProperty(
        override=OVERRIDABLE,
        name="Bones",
        description="Comma-separated bone names: the region's flesh is measured from these bones only "
                    "(e.g. the belly from the spine)",
        update=_settings_changed,
    )


class LVP_PG_settings(bpy.types.PropertyGroup):
    """Local Volume Preservation settings of one object."""

    effect: EnumProperty(
        override=OVERRIDABLE,
        name="Effect",
        description="How the lost volume is put back",
        items=EFFECT_ITEMS,
        default='ORGANIC',
        update=_settings_changed,
    )
    alpha: FloatProperty(
        override=OVERRIDABLE,
        name="Alpha",
        description="Concentration at the joints: higher keeps the correction closer to where no bone "
                    "dominates",
        default=1.0, min=0.0, soft_max=4.0,
        update=_settings_changed,
    )
    beta: FloatProperty(
        override=OVERRIDABLE,
        name="Beta",
        description="Dependence on the distance to the bones: higher moves flesh far from the bone more "
                    "than flesh over it",
        default=1.0, min=0.0, soft_max=4.0,
        update=_settings_changed,
    )
    iterations: IntProperty(
        override=OVERRIDABLE,
        name="Iterations",
        description="Correction passes per frame; 1 is the paper's single pass, more removes its "
                    "linearization error",
        default=8, min=1, max=64,
        update=_settings_changed,
    )
    tolerance: FloatProperty(
        override=OVERRIDABLE,
        name="Tolerance",
        description="The passes stop once every region is this close to its rest volume (percent of the "
                    "region's volume); larger saves passes and leaves more of the error",
        subtype='PERCENTAGE',
        default=0.01, min=0.001, max=10.0, soft_max=1.0, precision=3, step=1,
        update=_settings_changed,
    )
    fold_over: BoolProperty(
        override=OVERRIDABLE,
        name="Fold-Over Prevention",
        description="Keep the skin of a bending joint from folding through itself; squeezed flesh bulges "
                    "instead (paper 5.4)",
        default=False,
        update=_settings_changed,
    )
    painted_vertex_group: StringProperty(
        override=OVERRIDABLE,
        name="Painted Map",
        description="Vertex group whose weights say where the volume goes (Painted effect)",
        update=_settings_changed,
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
    previous_color_attribute: StringProperty(
        override=OVERRIDABLE,
        name="Previous Colour Attribute",
        description="Active colour attribute before the display was turned on (restored when it is turned off)",
        options={'HIDDEN'})


classes = (
    LVP_PG_region_restriction,
    LVP_PG_settings,
)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.lvp = PointerProperty(type=LVP_PG_settings, name="Local Volume Preservation",
                                           override=OVERRIDABLE)


def unregister():
    del bpy.types.Object.lvp
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
