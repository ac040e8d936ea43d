"""Per-part looks: the rig's parts (``volrig.bone_parts``: left arm, spine, head, ... or one per chain) listed on
the Volume object (``volrig.parts``), each visible or hidden, in its own colour and opacity, in Cycles.

Every baked frame, and the rest volume (``<rig file>_parts.vdb`` in the cache, written when the rig is bound),
holds per part ``density_<key>`` (the values on the part's voxels) and ``mask_<key>`` (1 on them); the rest volume
also ``density_outside`` (the voxels in no part). The material:

- value   = the sum of the visible parts' density_<part> and density_outside: the density of the volume whose
            hidden voxels are empty, so no shell of a hidden part is left (a hidden part's grid is not read at
            all: Cycles' volume lookups may pick one neighbour at random, so even density - density_<part>
            would leave speckles at the part's surface);
- opacity = the transfer function's, times (1 + sum_p mask_p (opacity_p visible_p - 1)) / (1 - sum_hidden mask_p):
            each part's opacity weighted by its mask, hidden parts' weight left out;
- colour  = the transfer function's, mixed towards a coloured part's colour by its mask: non-zero only within a
            voxel of the part's voxels, so the colour never reaches a neighbour beyond the shared voxel band.
Frames baked before the parts were found have no part grids: they render empty until baked again (the bake
re-bakes them: the parts are part of what a frame's file depends on).
"""
import os

import bpy

import volrig
from volrig import pipeline

from . import objects, scans

#: Colours offered to new parts (a part keeps its settings when the parts are found again).
PART_COLORS = [(0.9, 0.15, 0.1), (0.2, 0.55, 0.95), (0.95, 0.8, 0.2), (0.3, 0.8, 0.35), (0.7, 0.4, 0.9),
               (0.95, 0.5, 0.15), (0.3, 0.85, 0.8), (0.9, 0.4, 0.65)]
_PREFIX = "volrig part"


def rest_file(volume_obj) -> str:
    """The rest volume with its part grids: ``<rig file>_parts.vdb`` beside the rig file (one per rig, so undo
    never points at a file that is gone)."""
    return os.path.splitext(scans.rig_path(volume_obj))[0] + "_parts.vdb"


def shown_at_rest(volume_obj) -> str:
    """The file the Volume object shows when not playing a bake: the rest volume with parts (per-part looks on,
    with the tissue grids too when per-tissue looks are on), else the rest volume with tissues, else the source."""
    from . import tissue_looks
    s = volume_obj.volrig
    if s.use_parts and s.rig_file and os.path.exists(rest_file(volume_obj)):
        return rest_file(volume_obj)
    if s.use_tissues and os.path.exists(tissue_looks.rest_file(volume_obj)):
        return tissue_looks.rest_file(volume_obj)
    return scans.source_path(volume_obj)


def write_rest(volume_obj) -> None:
    """The rest volume's looks files: with per-part looks on (and a rig), the parts' grids and the tissues' (if on);
    with per-tissue looks on, also the tissues' alone (shown once per-part looks are turned off)."""
    from . import tissue_looks
    from .bake import RigState
    s = volume_obj.volrig
    if s.use_parts and "RIG" in objects.members(volume_obj):
        state = RigState(volume_obj)
        pipeline.write_rest_looks(rest_file(volume_obj), scans.source(volume_obj), state.points, state.binding,
                                  parts_of(volume_obj), scans.mask(volume_obj),
                                  tissues=tissue_looks.tissues_of(volume_obj),
                                  substitutes=substitutes_of(volume_obj))
    if s.use_tissues:
        tissue_looks.write_rest(volume_obj)


def parts_of(volume_obj):
    """The object's parts as ``volrig.Part`` (bone indices in the armature's order), for the bake and the
    material; none while per-part looks are off."""
    rig = objects.members(volume_obj).get("RIG")
    if rig is None or not volume_obj.volrig.use_parts:
        return []
    index = {b.name: i for i, b in enumerate(rig.data.bones)}
    out = []
    for p in volume_obj.volrig.parts:
        bones = [index[name] for name in p.bones.split(",") if name in index]
        if bones:
            out.append(volrig.Part(p.name, p.key, bones))
    return out


_LOADED = {}  # substitute file -> (modification time, Volume): loaded once per change


def substitutes_of(volume_obj) -> dict:
    """``{part key: Volume}`` of the parts given a substitute file (per-part looks on), loaded once per change of
    the file; VolrigError naming the part when a file cannot be read."""
    if not volume_obj.volrig.use_parts:
        return {}
    out = {}
    for p in volume_obj.volrig.parts:
        if not p.substitute:
            continue
        path = bpy.path.abspath(p.substitute)
        try:
            stamp = os.path.getmtime(path)
            held = _LOADED.get(path)
            if held is None or held[0] != stamp:
                held = _LOADED[path] = (stamp, volrig.load(path))
        except (OSError, ValueError) as e:
            raise volrig.VolrigError(f"the substitute of part {p.name!r}: {e}") from e
        out[p.key] = held[1]
    used = {bpy.path.abspath(p.substitute) for p in volume_obj.volrig.parts if p.substitute}
    for path in set(_LOADED) - used:  # (a full-resolution substitute no longer used is not kept)
        del _LOADED[path]
    return out


def tell(message: str) -> None:
    """A message in a popup where there is a window (a property's update cannot report), and on the console."""
    print(message)
    wm = bpy.context.window_manager
    if not bpy.app.background and wm is not None and wm.windows:
        wm.popup_menu(lambda menu, _c: menu.layout.label(text=message), title="volrig", icon="ERROR")


def substitute_changed(volume_obj) -> None:
    """A part's substitute file changed: the rest volume is written again (the bake follows: the substitutes are part
    of what a frame depends on); a file that cannot be read is reported (and again by the bake)."""
    if volume_obj.volrig.use_parts and "RIG" in objects.members(volume_obj):
        try:
            write_rest(volume_obj)
        except volrig.VolrigError as e:
            tell(f"volrig: {e}")
            return
        if not volume_obj.data.is_sequence:
            objects.point_volume_at(volume_obj, shown_at_rest(volume_obj))


def parts_toggled(volume_obj) -> None:
    """Per-part looks turned on (the parts found, the rest volume with their grids written and shown) or off (the
    source shown again), unless a bake is playing; the material follows."""
    from . import materials
    if volume_obj.volrig.use_parts and "RIG" in objects.members(volume_obj):
        refresh(volume_obj)
        return
    if not volume_obj.data.is_sequence:
        objects.point_volume_at(volume_obj, shown_at_rest(volume_obj))
    materials.update_volume_material(volume_obj)


def refresh(volume_obj) -> int:
    """Finds the rig's parts (keeping the settings of parts already listed by name); with per-part looks on,
    writes the rest volume with their grids and shows it unless a bake is playing; returns the number of parts."""
    from . import materials
    from .bake import RigState
    state = RigState(volume_obj)
    s = volume_obj.volrig
    kept = {p.name: (p.visible, p.colored, tuple(p.color), p.opacity) for p in s.parts}
    s.parts.clear()
    for k, part in enumerate(volrig.bone_parts(state.names, state.parents)):
        item = s.parts.add()
        item.name, item.key = part.name, part.key
        item.bones = ",".join(state.names[b] for b in part.bones)
        item.visible, item.colored, item.color, item.opacity = kept.get(
            part.name, (True, False, PART_COLORS[k % len(PART_COLORS)], 1.0))
    s.parts_index = min(s.parts_index, max(len(s.parts) - 1, 0))
    if s.use_parts:
        write_rest(volume_obj)
    if not volume_obj.data.is_sequence:
        objects.point_volume_at(volume_obj, shown_at_rest(volume_obj))
    materials.update_volume_material(volume_obj)
    return len(s.parts)


def route(tree, nd, parts, tissues, settings) -> None:
    """Links the material's value (into the transfer function's window), opacity and colour (into the shaders)
    through the parts' grids, or straight when ``parts`` is empty; ``nd``: materials' nodes by role. With
    ``tissues`` (a label map's classes: tissue_looks.py) the opacity and colour come from the tissues' grids
    (``materials.tissue_sums``) instead of the transfer function, the density multiplier kept. ``settings``: the
    volume's (value range and density multiplier, for parts with their own transfer function)."""
    from .materials import TISSUE_PREFIX, tissue_sums
    for node in [x for x in tree.nodes if x.name.startswith((_PREFIX, TISSUE_PREFIX))]:
        tree.nodes.remove(node)
    link = tree.links.new
    strength = nd["opacity"].inputs[0]
    for old in list(strength.links):
        tree.links.remove(old)
    value, opacity, colour = nd["density"].outputs["Fac"], nd["opacity"].outputs[0], nd["ramp"].outputs["Color"]
    sums = tissue_sums(tree, tissues, x=-2300, y=900) if len(tissues) else None
    if sums is not None:
        link(sums[0], strength)
        colour = sums[1]
    elif len(tissues):  # every tissue hidden
        strength.default_value = 0.0
    else:
        link(nd["ramp"].outputs["Alpha"], strength)
    if len(parts):
        value, opacity, colour = _part_nodes(tree, opacity, colour, parts, settings)
    link(value, nd["window"].inputs["Value"])
    for shader in (nd["scatter"], nd["absorb"]):
        link(colour, shader.inputs["Color"])
        link(opacity, shader.inputs["Density"])
    link(opacity, nd["glow_density"].inputs[1])


class _Builder:
    """Adds named, placed nodes to a material's tree."""

    def __init__(self, tree):
        self.tree = tree
        self.count = 0

    def node(self, kind, x, y, **props):
        nd = self.tree.nodes.new(kind)
        self.count += 1
        nd.name = nd.label = f"{_PREFIX} {self.count}"
        nd.location = (x, y)
        for k, v in props.items():
            setattr(nd, k, v)
        return nd

    def math(self, op, a, b, c=None, x=0, y=0):
        """A Math node ``op`` of inputs a, b (and c): each a socket to link or a number."""
        nd = self.node("ShaderNodeMath", x, y, operation=op)
        for socket, v in zip(nd.inputs, (a, b, c)):
            if isinstance(v, bpy.types.NodeSocket):
                self.tree.links.new(v, socket)
            elif v is not None:
                socket.default_value = v
        return nd.outputs[0]

    def attribute(self, name, x, y):
        return self.node("ShaderNodeAttribute", x, y, attribute_name=name).outputs["Fac"]

    def mix(self, fac, a, b_color, x, y):
        """Colour ``a`` (a socket) mixed towards ``b_color`` (a constant colour or a socket) by ``fac`` (a
        socket)."""
        nd = self.node("ShaderNodeMix", x, y, data_type="RGBA")
        self.tree.links.new(fac, nd.inputs[0])
        self.tree.links.new(a, nd.inputs[6])
        if isinstance(b_color, bpy.types.NodeSocket):
            self.tree.links.new(b_color, nd.inputs[7])
        else:
            nd.inputs[7].default_value = (*b_color, 1.0)
        return nd.outputs[2]


def _part_nodes(tree, opacity, colour, parts, settings):
    """The parts' nodes (see the module's description); returns the (value, opacity, colour) sockets. A part with
    its own transfer function (``preset``) takes its colour and opacity from its own ramp over ``density_<key>``
    where its mask is, instead of the volume's."""
    b = _Builder(tree)
    value, hidden_weight, opacity_weight = b.attribute(volrig.parts.OUTSIDE, -1900, -700), 0.0, 1.0
    own = None  # the opacity of the parts with their own transfer function
    for k, p in enumerate(parts):
        x, y = -1700 + 150 * k, -700 - 60 * k
        m = b.attribute(f"mask_{p.key}", x, y - 500)
        hide = 0.0 if p.visible else 1.0
        preset = p.preset
        if p.visible:
            density = b.attribute(f"density_{p.key}", x, y - 300)
            value = b.math("ADD", density, value, x=x, y=y)
            if preset != "VOLUME":
                ramp = _own_ramp(b, density, preset, settings, x, y - 900)
                colour = b.mix(m, colour, ramp.outputs["Color"], x=x, y=y - 700)
                alpha = b.math("MULTIPLY", ramp.outputs["Alpha"], p.opacity * settings.density_scale, x=x, y=y - 1100)
                term = b.math("MULTIPLY", m, alpha, x=x, y=y - 1200)
                own = term if own is None else b.math("ADD", own, term, x=x, y=y - 1300)
        hidden_weight = b.math("MULTIPLY_ADD", m, hide, hidden_weight, x=x, y=y - 100)
        kept = p.opacity * (1.0 - hide) if preset == "VOLUME" else 0.0  # (an own ramp replaces the volume's)
        opacity_weight = b.math("MULTIPLY_ADD", m, kept - 1.0, opacity_weight, x=x, y=y - 200)
        if p.colored and p.visible and preset == "VOLUME":
            colour = b.mix(m, colour, p.color, x=x, y=y - 700)
    weight = b.math("MAXIMUM", b.math("SUBTRACT", 1.0, hidden_weight, x=-300, y=-900), 1e-4, x=-150, y=-900)
    share = b.math("DIVIDE", opacity_weight, weight, x=0, y=-900)
    opacity = b.math("MULTIPLY", opacity, share, x=150, y=-900)
    if own is not None:
        opacity = b.math("ADD", opacity, own, x=300, y=-900)
    return value, opacity, colour


def _own_ramp(b, density, preset, settings, x, y):
    """A part's own window and ramp (``preset`` over the volume's value range) on its ``density`` socket."""
    from .materials import fill_ramp, part_transfer
    lo, hi, interpolation, stops = part_transfer(preset, settings)
    window = b.node("ShaderNodeMapRange", x, y, clamp=True)
    window.inputs["From Min"].default_value = lo
    window.inputs["From Max"].default_value = hi if hi > lo else lo + 1.0
    b.tree.links.new(density, window.inputs["Value"])
    ramp = b.node("ShaderNodeValToRGB", x, y - 100)
    fill_ramp(ramp.color_ramp, interpolation, stops)
    b.tree.links.new(window.outputs["Result"], ramp.inputs["Fac"])
    return ramp
