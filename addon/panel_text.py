# SPDX-License-Identifier: GPL-3.0-or-later
"""Fitting the panel's texts into the Properties editor: how wide a text is in Blender's interface
font, and a sentence wrapped over as many labels as it needs.

A label that is too wide is cut by Blender with an ellipsis in its middle, which loses exactly the
words that say what is wrong. Messages (a status, a warning) are sentences, so they are wrapped at
the region's width; everything else is kept short enough to fit the default layout (test_panel.py
checks it at the width of the factory layout's Properties editor).

Widths are in pixels at the interface scale; the margins are those of Blender's panels, as measured
on screenshots of 3.4 and 5.2 (a little more, never less).
"""

import blf
import bpy

# Blender's layout, in pixels at scale 1.
PANEL_MARGINS = 36.0   # both sides of a panel's (or sub-panel's) content within its region
BOX_MARGINS = 10.0     # both sides of a box's content within the box
TEXT_MARGINS = 12.0    # both sides of a label's or button's text within the label or button
ICON_WIDTH = 20.0      # an icon before a text, or a checkbox
PROPERTY_SPLIT = 0.4   # the share of the width that use_property_split gives the property's name

# The Properties editor of Blender's factory layout on a 1920x1080 screen: its region 303 px wide at
# the scale 1.042 that Xvfb's 96 dpi gives (3.4; 309 px on 5.2). Used where no region is at hand.
DEFAULT_REGION_WIDTH = 303.0
DEFAULT_SCALE = 1.0417


def scale_of(context):
    """The interface scale: the user's resolution scale times the display's (0 headless: 1)."""
    preferences = getattr(context, "preferences", None)
    scale = preferences.system.ui_scale if preferences is not None else 0.0
    return scale if scale > 0.0 else DEFAULT_SCALE


def region_width(context):
    region = getattr(context, "region", None)
    return float(region.width) if region is not None and region.width > 0 else DEFAULT_REGION_WIDTH


def content_width(context, boxed=False):
    """Room for a text in the panel of context's region (boxed: inside a box of it, or in a
    sub-panel, whose content is inset as a box's is)."""
    margins = PANEL_MARGINS + TEXT_MARGINS + (BOX_MARGINS if boxed else 0.0)
    return region_width(context) - margins * scale_of(context)


def text_width(text, scale):
    """The width of text in the interface font (font 0, widget text of 11 points by default) at
    scale, in pixels."""
    blf.size(0, bpy.context.preferences.ui_styles[0].widget.points * scale)
    return blf.dimensions(0, text)[0]


def wrap(text, room, scale):
    """text split at spaces into lines no wider than room (a single word wider than room keeps a line
    of its own)."""
    lines = []
    current = ""
    for word in text.split():
        candidate = word if not current else current + " " + word
        if not current or text_width(candidate, scale) <= room:
            current = candidate
        else:
            lines.append(current)
            current = word
    if current:
        lines.append(current)
    return lines or [""]


def wrapped_label(layout, context, text, icon='NONE', boxed=False):
    """text as labels on consecutive lines, each fitting the panel (boxed: as content_width); the
    icon (if any) on the first, the other lines indented under its text."""
    scale = scale_of(context)
    room = content_width(context, boxed) - (ICON_WIDTH * scale if icon != 'NONE' else 0.0)
    column = layout.column(align=True)
    for index, line in enumerate(wrap(text, room, scale)):
        if icon == 'NONE':
            column.label(text=line)
        else:
            column.label(text=line, icon=icon if index == 0 else 'BLANK1')
