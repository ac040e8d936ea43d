"""The Cycles volume material of a volrig Volume object: a transfer function (a colour ramp over the ``density``
grid, the scan's own values) driving scattering and absorption, a density multiplier, a glow on the voxels of
one bone read from the baked ``bone`` grid (bone index + 1 in the armature's bone order, 0 = empty), and each
part's look (visible, colour, opacity: looks.py)."""
import bpy

import volrig

from . import compat, engines
from .state import members, tissues_of

#: Transfer functions: the value window as fractions of the volume's value range, and ramp stops
#: (position, (r, g, b), opacity) over that window.
PRESETS = {
    "CT_BONE": (0.45, 1.0, "LINEAR", [(0.0, (0.55, 0.25, 0.2), 0.0), (0.25, (0.85, 0.75, 0.65), 0.3),
                                      (1.0, (1.0, 0.98, 0.95), 1.0)]),
    "SOFT_TISSUE": (0.05, 1.0, "LINEAR", [(0.0, (0.6, 0.15, 0.1), 0.0), (0.15, (0.8, 0.35, 0.3), 0.12),
                                          (0.5, (0.9, 0.65, 0.55), 0.25), (1.0, (1.0, 1.0, 0.95), 1.0)]),
    "GREY": (0.0, 1.0, "LINEAR", [(0.0, (1.0, 1.0, 1.0), 0.0), (1.0, (1.0, 1.0, 1.0), 1.0)]),
}
#: The lumen view's wall colour (a mucosa pink) and the colour of the lumen itself (clear).
WALL_COLOR = (0.9, 0.45, 0.4)
#: Label colours (label k uses PALETTE[(k - 1) % len]); a colour ramp holds at most 32 stops.
PALETTE = volrig.tissues.LABEL_COLORS


def _lumen_range(s):
    """The values the lumen holds: the segmentation's range, or its labels' span (label maps)."""
    if s.segment_by == "LABELS":
        from volrig.pipeline import parse_labels
        try:
            labels = parse_labels(s.labels)
        except Exception:  # an invalid label text: the count shows it; the look falls back to label 1
            labels = [1]
        return min(labels) - 0.5, max(labels) + 0.5
    return s.low, s.high


def _stops(preset, vmin, vmax, lumen=None, palette=None):
    if preset == "LUMEN":  # the lumen's values clear, everything else an opaque wall: seen from inside
        lo, hi = lumen
        span = (vmax - vmin) or 1.0
        edge = 0.02
        a = min(max((lo - vmin) / span, 0.0), 1.0)
        b = min(max((hi - vmin) / span, 0.0), 1.0)
        stops = [(0.0, WALL_COLOR, 1.0)] if a > edge else []
        stops += [(max(a - edge, 0.0), WALL_COLOR, 1.0), (a, WALL_COLOR, 0.0), (max(b, a), WALL_COLOR, 0.0)]
        if b < 1.0 - edge:
            stops += [(min(b + edge, 1.0), WALL_COLOR, 1.0), (1.0, WALL_COLOR, 1.0)]
        if a <= 0.0:
            stops = stops[1:]  # nothing below the lumen
        return vmin, vmin + span, "LINEAR", stops
    if preset == "LABELS":
        top = max(1, min(int(round(vmax)), 31))
        stops = [(0.0, (0.0, 0.0, 0.0), 0.0)]
        colours = [tuple(c) for c in palette] if palette else PALETTE  # an imported drawing's own colours
        stops += [((k - 0.5) / top, colours[(k - 1) % len(colours)], 1.0) for k in range(1, top + 1)]
        return 0.0, float(top), "CONSTANT", stops
    lo, hi, interpolation, stops = PRESETS[preset]
    span = (vmax - vmin) or 1.0
    return vmin + lo * span, vmin + hi * span, interpolation, stops


def _nodes(mat):
    """The material's nodes by role, building the tree on first use."""
    tree = mat.node_tree
    n = tree.nodes
    if "volrig ramp" in n:
        return {k: n["volrig " + k] for k in ("density", "window", "ramp", "opacity", "scatter", "absorb", "bone",
                                              "is_bone", "glow", "glow_density", "emit")}
    n.clear()
    link = tree.links.new

    def node(kind, key, x, y):
        nd = n.new(kind)
        nd.name = nd.label = "volrig " + key
        nd.location = (x, y)
        return nd

    density = node("ShaderNodeAttribute", "density", -900, 0)
    density.attribute_name = "density"
    window = node("ShaderNodeMapRange", "window", -700, 0)
    window.clamp = True
    ramp = node("ShaderNodeValToRGB", "ramp", -500, 0)
    opacity = node("ShaderNodeMath", "opacity", -200, -150)
    opacity.operation = "MULTIPLY"
    scatter = node("ShaderNodeVolumeScatter", "scatter", 0, 150)
    absorb = node("ShaderNodeVolumeAbsorption", "absorb", 0, -50)
    bone = node("ShaderNodeAttribute", "bone", -900, -400)
    bone.attribute_name = "bone"
    is_bone = node("ShaderNodeMath", "is_bone", -700, -400)
    is_bone.operation = "COMPARE"
    # Cycles interpolates the label grid: only values within 0.05 of the label count (between two labels or at
    # the surface the interpolated value passes the label in a thin shell only)
    is_bone.inputs[2].default_value = 0.05
    glow = node("ShaderNodeMath", "glow", -500, -400)
    glow.operation = "MULTIPLY"
    glow_density = node("ShaderNodeMath", "glow_density", -300, -400)
    glow_density.operation = "MULTIPLY"
    emit = node("ShaderNodeEmission", "emit", 0, -300)
    add1 = n.new("ShaderNodeAddShader")
    add1.location = (200, 50)
    add2 = n.new("ShaderNodeAddShader")
    add2.location = (350, -50)
    out = n.new("ShaderNodeOutputMaterial")
    out.location = (550, 0)
    link(density.outputs["Fac"], window.inputs["Value"])
    link(window.outputs["Result"], ramp.inputs["Fac"])
    link(ramp.outputs["Alpha"], opacity.inputs[0])
    for shader in (scatter, absorb):
        link(ramp.outputs["Color"], shader.inputs["Color"])
        link(opacity.outputs[0], shader.inputs["Density"])
    link(bone.outputs["Fac"], is_bone.inputs[0])
    link(is_bone.outputs[0], glow.inputs[0])
    link(glow.outputs[0], glow_density.inputs[0])
    link(opacity.outputs[0], glow_density.inputs[1])
    link(glow_density.outputs[0], emit.inputs["Strength"])
    link(scatter.outputs[0], add1.inputs[0])
    link(absorb.outputs[0], add1.inputs[1])
    link(add1.outputs[0], add2.inputs[0])
    link(emit.outputs[0], add2.inputs[1])
    link(add2.outputs[0], out.inputs["Volume"])
    return _nodes(mat)


def fill_ramp(ramp, interpolation, stops) -> None:
    """A colour ramp set to ``stops`` ((position, (r, g, b), alpha), ...) with ``interpolation``."""
    ramp.interpolation = interpolation
    while len(ramp.elements) > 1:
        ramp.elements.remove(ramp.elements[-1])
    ramp.elements[0].position = stops[0][0]
    ramp.elements[0].color = (*stops[0][1], stops[0][2])
    for pos, rgb, alpha in stops[1:]:
        ramp.elements.new(pos).color = (*rgb, alpha)


def part_transfer(preset, settings):
    """(window low, window high, interpolation, stops) of a part's own preset over the volume's value range."""
    return _stops(preset, settings.value_min, settings.value_max)


def bone_index(volume_obj, name: str) -> int:
    """1-based index of bone ``name`` in the rig (the ``bone`` grid's label), 0 when there is no such bone."""
    rig = members(volume_obj).get("RIG")
    if rig is None or not name:
        return 0
    names = [b.name for b in rig.data.bones]
    return names.index(name) + 1 if name in names else 0


def update_volume_material(volume_obj):
    """Create or update the object's material from its settings (preset, density, highlighted bone)."""
    s = volume_obj.volrig
    data = volume_obj.data
    if not isinstance(data, bpy.types.Volume):
        return None
    mat = data.materials[0] if len(data.materials) and data.materials[0] is not None else None
    if mat is None:
        mat = bpy.data.materials.new(volume_obj.name + " volume")
        compat.use_nodes(mat)
        if len(data.materials):
            data.materials[0] = mat
        else:
            data.materials.append(mat)
    nd = _nodes(mat)
    palette = volume_obj.get("volrig_palette")
    palette = [tuple(palette[i:i + 3]) for i in range(0, len(palette), 3)] if palette else None
    lo, hi, interpolation, stops = _stops(s.preset, s.value_min, s.value_max, _lumen_range(s), palette)
    nd["window"].inputs["From Min"].default_value = lo
    nd["window"].inputs["From Max"].default_value = hi if hi > lo else lo + 1.0
    fill_ramp(nd["ramp"].color_ramp, interpolation, stops)
    nd["opacity"].inputs[1].default_value = s.density_scale
    nd["absorb"].inputs["Density"].default_value = 0.0
    index = bone_index(volume_obj, s.highlight_bone)
    nd["is_bone"].inputs[1].default_value = float(index) if index else -10.0
    nd["glow"].inputs[1].default_value = s.highlight_strength
    nd["emit"].inputs["Color"].default_value = (*s.highlight_color, 1.0)
    route(mat.node_tree, nd, s.parts if s.use_parts else [], tissues_of(volume_obj), s)
    engines.check_material(mat)  # (EEVEE reads a limited number of grids: says so when this look needs more)
    return mat


def lumen_wall_material(name: str, density: float):
    """The material of a lumen's wall (``<name>_lumen``, a grid 0 in the lumen and 1 in the wall around it):
    a scattering and absorbing medium of albedo WALL_COLOR, ``density`` per Blender unit where the grid is 1, so the wall
    is opaque within a voxel or two and the headlight shades it like tissue."""
    mat = bpy.data.materials.new(name)
    compat.use_nodes(mat)
    n = mat.node_tree.nodes
    n.clear()
    attr = n.new("ShaderNodeAttribute")
    attr.attribute_name = "density"
    attr.location = (-600, 0)
    mult = n.new("ShaderNodeMath")
    mult.operation = "MULTIPLY"
    mult.inputs[1].default_value = float(density)
    mult.location = (-400, 0)
    absorb_density = n.new("ShaderNodeMath")
    absorb_density.operation = "MULTIPLY"
    absorb_density.inputs[1].default_value = 1.5
    absorb_density.location = (-200, -150)
    scatter = n.new("ShaderNodeVolumeScatter")
    scatter.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    scatter.location = (0, 100)
    absorb = n.new("ShaderNodeVolumeAbsorption")
    # in an opaque medium the colour is the albedo, scattering / (scattering + absorption), not the scattering
    # colour: absorption (1 - colour) * 1.5 * density against white scattering gives albedo WALL_COLOR
    absorb.inputs["Color"].default_value = (*(max(1.0 - (1.0 - c) / c / 1.5, 0.0) for c in WALL_COLOR), 1.0)
    absorb.location = (0, -100)
    add = n.new("ShaderNodeAddShader")
    add.location = (200, 0)
    out = n.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    link = mat.node_tree.links.new
    link(attr.outputs["Fac"], mult.inputs[0])
    link(mult.outputs[0], scatter.inputs["Density"])
    link(mult.outputs[0], absorb_density.inputs[0])
    link(absorb_density.outputs[0], absorb.inputs["Density"])
    link(scatter.outputs[0], add.inputs[0])
    link(absorb.outputs[0], add.inputs[1])
    link(add.outputs[0], out.inputs["Volume"])
    return mat


#: Thickness colours, thin to thick (a perceptually ordered blue-green-yellow-red ramp).
THICKNESS_STOPS = ((0.0, (0.05, 0.15, 0.9)), (0.35, (0.0, 0.75, 0.6)), (0.65, (0.95, 0.85, 0.1)),
                   (1.0, (0.9, 0.1, 0.05)))


def thickness_material(name: str):
    """``<name> thickness``: a Principled Volume whose density follows the ``density`` grid (the mask) and whose
    colour and glow follow the ``thickness`` grid through a colour ramp (``set_thickness_range`` sets the span)."""
    mat = bpy.data.materials.new(f"{name} thickness")
    compat.use_nodes(mat)
    n = mat.node_tree.nodes
    n.clear()
    ramp = _thickness_ramp(mat.node_tree, -200)
    vol = n.new("ShaderNodeVolumePrincipled")
    vol.name = "volrig thickness volume"
    vol.location = (-100, 0)
    # the glow only inside the mask (Principled Volume's emission ignores its density attribute: a constant
    # strength would light the grid's whole active box)
    inside = n.new("ShaderNodeAttribute")
    inside.attribute_name = "density"
    inside.location = (-600, -250)
    glow = n.new("ShaderNodeMath")
    glow.operation = "MULTIPLY"
    glow.inputs[1].default_value = 0.6
    glow.location = (-400, -250)
    out = n.new("ShaderNodeOutputMaterial")
    out.location = (200, 0)
    link = mat.node_tree.links.new
    link(ramp.outputs["Color"], vol.inputs["Color"])
    link(ramp.outputs["Color"], vol.inputs["Emission Color"])
    link(inside.outputs["Fac"], glow.inputs[0])
    link(glow.outputs[0], vol.inputs["Emission Strength"])
    link(vol.outputs["Volume"], out.inputs["Volume"])
    return mat


def _thickness_ramp(tree, location):
    """Attribute ``thickness`` -> map range 0..top (``volrig thickness span``) -> THICKNESS_STOPS ramp, linked, in
    node tree ``tree``, ending at x = ``location``; returns the ramp node."""
    n = tree.nodes
    attr = n.new("ShaderNodeAttribute")
    attr.name = attr.label = "volrig thickness"
    attr.attribute_name = "thickness"
    attr.location = (location - 600, 0)
    span = n.new("ShaderNodeMapRange")
    span.name = span.label = "volrig thickness span"
    span.location = (location - 400, 0)
    ramp = n.new("ShaderNodeValToRGB")
    ramp.name = ramp.label = "volrig thickness ramp"
    ramp.location = (location - 200, 0)
    r = ramp.color_ramp
    r.elements[0].position, r.elements[0].color = THICKNESS_STOPS[0][0], (*THICKNESS_STOPS[0][1], 1.0)
    r.elements[1].position, r.elements[1].color = THICKNESS_STOPS[-1][0], (*THICKNESS_STOPS[-1][1], 1.0)
    for pos, rgb in THICKNESS_STOPS[1:-1]:
        r.elements.new(pos).color = (*rgb, 1.0)
    tree.links.new(attr.outputs["Fac"], span.inputs["Value"])
    tree.links.new(span.outputs["Result"], ramp.inputs["Fac"])
    return ramp


def medial_material(name: str):
    """``<name> medial``: a two-sided Principled BSDF whose base colour follows the mesh's ``thickness`` point
    attribute through the thickness ramp (``set_medial_range`` sets the span)."""
    mat = bpy.data.materials.new(f"{name} medial")
    compat.use_nodes(mat)
    mat.use_backface_culling = False
    n = mat.node_tree.nodes
    n.clear()
    ramp = _thickness_ramp(mat.node_tree, 0)
    bsdf = n.new("ShaderNodeBsdfPrincipled")
    bsdf.name = "volrig medial bsdf"
    bsdf.location = (100, 0)
    bsdf.inputs["Roughness"].default_value = 0.6
    out = n.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    link = mat.node_tree.links.new
    link(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def set_medial_range(mat, top: float) -> None:
    """Thickness 0 .. ``top`` (world units) spans the ramp of a medial_material."""
    span = mat.node_tree.nodes["volrig thickness span"]
    span.inputs["From Min"].default_value = 0.0
    span.inputs["From Max"].default_value = max(float(top), 1e-6)


def set_thickness_range(mat, top: float, density: float) -> None:
    """Thickness 0 .. ``top`` (world units) spans the ramp; ``density`` per Blender unit inside the mask."""
    n = mat.node_tree.nodes
    span = n["volrig thickness span"]
    span.inputs["From Min"].default_value = 0.0
    span.inputs["From Max"].default_value = max(float(top), 1e-6)
    n["volrig thickness volume"].inputs["Density"].default_value = float(density)


#: Names of the nodes tissue_sums adds (looks.route removes them before building again).
TISSUE_PREFIX = "volrig tissue look"


#: Half-width, in code units, of the match between the ``density`` grid and a class's codes (``tissue_sums``).
CODE_MATCH = 0.5


def tissue_sums(tree, tissues, x=-1100, y=0):
    """The nodes summing a label map's visible tissues in node tree ``tree`` from its ``tissue`` grid (each voxel's
    class index k, ``tissues`` in class-index order: ``volrig.tissue_grid``) and its ``density`` grid (the codes):
    each class adds its opacity (a Value node) times its weight to the density, and its colour (an RGB node)
    weighted the same way to the colour. Returns the (density, mean colour) sockets, or None when no tissue is
    visible. A hidden tissue adds nothing.

    Both grids interpolate, so between two classes the index passes the classes in between. Class k's weight is
    max(0, 1 - |v - k|) (v: the interpolated index) times how well the interpolated code d matches one of its codes
    c scaled by v / k, max(0, 1 - |d - c v / k| / CODE_MATCH): inside the class d = c, and across its boundary with
    the outside (0) d = c v / k exactly (the class fades out over the last 1 / k of the voxel there: skin, class 1,
    as an occupancy would), whereas a class the index passes between two others matches only where two lines
    cross, a film of about a hundredth of a voxel. Between two classes both fade out within a fraction of the voxel
    (a gap rather than a third class). Nodes are named ``<TISSUE_PREFIX> opacity <key>``, ``... colour <key>`` and
    so on."""
    link = tree.links.new

    def node(kind, label, dx, dy, **props):
        nd = tree.nodes.new(kind)
        nd.name = nd.label = f"{TISSUE_PREFIX} {label}"
        nd.location = (x + dx, y + dy)
        for k, v in props.items():
            setattr(nd, k, v)
        return nd

    def math(op, label, dx, dy, *inputs, clamp=False):
        nd = node("ShaderNodeMath", label, dx, dy, operation=op, use_clamp=clamp)
        for socket, v in zip(nd.inputs, inputs):
            if isinstance(v, bpy.types.NodeSocket):
                link(v, socket)
            else:
                socket.default_value = float(v)
        return nd.outputs[0]

    density, colour = None, None
    index = code = None
    for k, t in [(k, t) for k, t in enumerate(tissues) if t.visible]:
        dy = -220 * k
        if index is None:
            index = node("ShaderNodeAttribute", "grid", -1000, 0, attribute_name=volrig.tissues.GRID).outputs["Fac"]
            code = node("ShaderNodeAttribute", "codes", -1000, -200, attribute_name="density").outputs["Fac"]
        scaled = math("MULTIPLY", f"scaled {t.key}", -800, dy, index, 1.0 / (k + 1))
        offset = math("ABSOLUTE", f"offset {t.key}", -700, dy - 60, math("SUBTRACT", f"index {t.key}", -800, dy - 60,
                                                                         index, k + 1.0))
        near = math("SUBTRACT", f"indicator {t.key}", -600, dy, 1.0, offset, clamp=True)
        match = None
        for n, c in enumerate(t.codes):
            off = math("MULTIPLY_ADD", f"code {t.key} {c}", -700 + 40 * n, dy - 120, scaled, -float(c), code)
            away = math("ABSOLUTE", f"code distance {t.key} {c}", -680 + 40 * n, dy - 140, off)
            one = math("MULTIPLY_ADD", f"code match {t.key} {c}", -660 + 40 * n, dy - 160, away,
                       -1.0 / CODE_MATCH, 1.0, clamp=True)
            match = one if match is None else math("ADD", f"code sum {t.key} {c}", -640 + 40 * n, dy - 180,
                                                     match, one)
        gate = math("MULTIPLY", f"gate {t.key}", -400, dy, near, match if match is not None else 0.0)
        opacity = node("ShaderNodeValue", f"opacity {t.key}", 0, dy - 110)
        opacity.outputs[0].default_value = t.opacity
        rgb = node("ShaderNodeRGB", f"colour {t.key}", 200, dy - 60)
        rgb.outputs[0].default_value = (*t.color, 1.0)
        weight = node("ShaderNodeMath", f"weight {t.key}", 200, dy + 60, operation="MULTIPLY")
        link(gate, weight.inputs[0])
        link(opacity.outputs[0], weight.inputs[1])
        tinted = node("ShaderNodeVectorMath", f"tinted {t.key}", 400, dy, operation="SCALE")
        link(rgb.outputs[0], tinted.inputs[0])
        link(weight.outputs[0], tinted.inputs["Scale"])
        if colour is None:
            density, colour = weight.outputs[0], tinted.outputs[0]
            continue
        d = node("ShaderNodeMath", f"density sum {k}", 600, dy + 60, operation="ADD")
        link(density, d.inputs[0])
        link(weight.outputs[0], d.inputs[1])
        c = node("ShaderNodeVectorMath", f"colour sum {k}", 600, dy, operation="ADD")
        link(colour, c.inputs[0])
        link(tinted.outputs[0], c.inputs[1])
        density, colour = d.outputs[0], c.outputs[0]
    if colour is None:
        return None
    floor = node("ShaderNodeMath", "density floor", 800, 200, operation="MAXIMUM")
    link(density, floor.inputs[0])
    floor.inputs[1].default_value = 1e-4
    inverse = node("ShaderNodeMath", "inverse density", 950, 200, operation="DIVIDE")
    inverse.inputs[0].default_value = 1.0
    link(floor.outputs[0], inverse.inputs[1])
    mean = node("ShaderNodeVectorMath", "mean colour", 1000, 0, operation="SCALE")
    link(colour, mean.inputs[0])
    link(inverse.outputs[0], mean.inputs["Scale"])
    return density, mean.outputs[0]


def tissue_material(name: str, tissues, strength: float = 1.0):
    """``<name> tissues``: a Principled Volume over a label map's ``tissue`` grid of class indices (written by a bake
    with tissue looks: ``volrig.tissue_grid``), colour and density from ``tissue_sums``;
    ``volrig tissue strength`` scales the density (per world unit of the volume's grid)."""
    mat = bpy.data.materials.new(f"{name} tissues")
    compat.use_nodes(mat)
    tree = mat.node_tree
    tree.nodes.clear()
    vol = tree.nodes.new("ShaderNodeVolumePrincipled")
    vol.name = vol.label = "volrig tissue volume"
    vol.location = (300, 0)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.location = (600, 0)
    tree.links.new(vol.outputs["Volume"], out.inputs["Volume"])
    sums = tissue_sums(tree, tissues)
    if sums is None:  # nothing visible
        vol.inputs["Density"].default_value = 0.0
        return mat
    scaled = tree.nodes.new("ShaderNodeMath")
    scaled.name = scaled.label = "volrig tissue strength"
    scaled.operation = "MULTIPLY"
    scaled.location = (100, -200)
    tree.links.new(sums[0], scaled.inputs[0])
    scaled.inputs[1].default_value = float(strength)
    tree.links.new(sums[1], vol.inputs["Color"])
    tree.links.new(scaled.outputs[0], vol.inputs["Density"])
    return mat


# ---- the parts' and tissues' looks in the volume material (looks.py, tissue_looks.py) -----------------------------

_PREFIX = "volrig part"


def route(tree, nd, parts, tissues, settings) -> None:
    """Links the material's value (into the transfer function's window), opacity and colour (into the shaders)
    through the parts' grids, or straight when ``parts`` is empty; ``nd``: materials' nodes by role. With
    ``tissues`` (a label map's classes: tissue_looks.py) the opacity and colour come from the tissues' grids
    (``materials.tissue_sums``) instead of the transfer function, the density multiplier kept. ``settings``: the
    volume's (value range and density multiplier, for parts with their own transfer function)."""
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
    lo, hi, interpolation, stops = part_transfer(preset, settings)
    window = b.node("ShaderNodeMapRange", x, y, clamp=True)
    window.inputs["From Min"].default_value = lo
    window.inputs["From Max"].default_value = hi if hi > lo else lo + 1.0
    b.tree.links.new(density, window.inputs["Value"])
    ramp = b.node("ShaderNodeValToRGB", x, y - 100)
    fill_ramp(ramp.color_ramp, interpolation, stops)
    b.tree.links.new(window.outputs["Result"], ramp.inputs["Fac"])
    return ramp
