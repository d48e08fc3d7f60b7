# SPDX-License-Identifier: GPL-3.0-or-later
"""Names shared by the add-on's modules: the modifier, its node group, the offsets object and the
mesh attributes.

The names are a contract between the node group (which writes and reads them inside Blender's
modifier evaluation) and the handlers (which read them from the evaluated mesh and write the
offsets into the object that holds them). Changing one means changing files saved with the add-on.
"""

# The Geometry Nodes modifier placed right after the Armature modifier.
MODIFIER_NAME = "Volume Preservation"
# Its node group, built by code (node_group.py), shared by every object that uses the add-on.
NODE_GROUP_NAME = "Volume Preservation"
# Custom property on the node group that marks it as ours, with the version of its layout.
NODE_GROUP_TAG = "lvp_node_group_version"
NODE_GROUP_VERSION = 2
# The node group's Object input: the object whose mesh holds the correction (offsets.py).
OFFSETS_SOCKET_NAME = "Offsets"

# The object that holds one object's correction: a mesh of loose vertices, one per vertex of the
# corrected mesh, whose positions are the per-vertex offsets added to what leaves the Armature
# modifier. Written by the handlers every frame; zero means pass-through. Not in any collection: it
# is kept (and saved) because the modifier uses it. Its custom property OFFSETS_OWNER_TAG names the
# object it was made for.
OFFSETS_OBJECT_PREFIX = "Volume Preservation offsets: "
OFFSETS_OWNER_TAG = "lvp_offsets_of"

# Point attribute on the ORIGINAL mesh from which a node group of another layout reads the offsets:
# files whose node group reads it keep it (zero) until object.lvp_remove removes it.
OFFSET_ATTRIBUTE = "lvp_offset"
# Point attributes that exist only on the EVALUATED mesh, written by the node group: the positions
# that enter the modifier (what the Armature modifier produced) and the original vertex index,
# which lets the handlers find the original vertices again after a Subdivision Surface modifier.
CAPTURED_POSITION_ATTRIBUTE = "lvp_position"
CAPTURED_INDEX_ATTRIBUTE = "lvp_index"

# Colour attributes for the viewport display of the segmentation and of the correction map.
SEGMENTATION_ATTRIBUTE = "lvp_segmentation"
CORRECTION_MAP_ATTRIBUTE = "lvp_correction_map"

# Every attribute the add-on may leave on the original mesh (removed by object.lvp_remove); the
# captured ones only when the modifier was applied (Ctrl A), which makes them real.
ORIGINAL_MESH_ATTRIBUTES = (OFFSET_ATTRIBUTE, SEGMENTATION_ATTRIBUTE, CORRECTION_MAP_ATTRIBUTE,
                            CAPTURED_POSITION_ATTRIBUTE, CAPTURED_INDEX_ATTRIBUTE)
