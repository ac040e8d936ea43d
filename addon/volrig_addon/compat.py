"""What differs between the Blender versions volrig supports (3.4 .. 5.x), in one place.

- Keyframes: written through the action's slot and its channelbag where actions are slotted (Blender 4.4 and newer;
  ``Action.fcurves`` is gone in 5.0), through ``Action.fcurves`` before: mocap, fly-throughs, straightening and the
  contact markers' tests use :func:`fcurves` and :func:`new_fcurve`.
- Node trees: ``Material.use_nodes`` / ``World.use_nodes`` are needed before 5.0 and deprecated in 5.x (always on;
  removed in 6.0): :func:`use_nodes`.
- File-path properties that hold blend-relative ("//") paths say so in 5.x (:data:`BLEND_RELATIVE`; 5.x warns when
  such a path is set otherwise, and older versions refuse the option)."""
import bpy

#: Actions have slots and channelbags from Blender 4.4 on.
SLOTTED = bpy.app.version >= (4, 4, 0)

#: The ``options`` of a file-path property holding "//" paths (the default, animatable, before 5.0).
BLEND_RELATIVE = {"PATH_SUPPORTS_BLEND_RELATIVE"} if bpy.app.version >= (5, 0, 0) else {"ANIMATABLE"}


def fcurves(id_data, create: bool = True):
    """The F-curve collection animating ``id_data``: its action's channelbag for its slot (4.4+) or the action's
    F-curves (before). With ``create`` the animation data, action, slot and channelbag are made when missing;
    without it, None when any is missing."""
    ad = id_data.animation_data
    if ad is None:
        if not create:
            return None
        ad = id_data.animation_data_create()
    if ad.action is None:
        if not create:
            return None
        ad.action = bpy.data.actions.new(f"{id_data.name}Action")
    action = ad.action
    if not SLOTTED:
        return action.fcurves
    from bpy_extras import anim_utils

    slot = ad.action_slot
    if slot is None:
        if not create:
            return None
        slot = action.slots.new(id_type=id_data.id_type, name=id_data.name)
        ad.action_slot = slot
    if create:
        return anim_utils.action_ensure_channelbag_for_slot(action, slot).fcurves
    bag = anim_utils.action_get_channelbag_for_slot(action, slot)
    return None if bag is None else bag.fcurves


def new_fcurve(curves, path: str, index: int = 0, group: str = ""):
    """A new F-curve in ``curves`` (from :func:`fcurves`) for ``path``[``index``], in the channel group ``group``."""
    if SLOTTED:
        return curves.new(path, index=index, group_name=group)
    return curves.new(path, index=index, action_group=group) if group else curves.new(path, index=index)


def use_nodes(idblock) -> None:
    """Makes a material or world use its node tree: ``use_nodes`` before Blender 5.0; 5.x always does (and warns)."""
    if bpy.app.version < (5, 0, 0):
        idblock.use_nodes = True
