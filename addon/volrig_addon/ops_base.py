"""What the feature modules' operators and panels share: user errors reported in the UI (``USER_ERRORS``,
``_reported``), the progress bar, the volume an operator works on (``_OnVolume``), and the sidebar panels' base
(``_VolrigPanel``) and layout helpers. Operators: thin over the volrig package, whose pipeline
(``volrig.pipeline``) does every step. Each reports user mistakes (volrig's own errors: bad files, empty
segmentations, missing rigs; and OSError) in the UI instead of raising, lets anything else (a bug) raise, is
undoable, and never writes to the user's source file."""
import textwrap

import volrig

from . import objects

#: What a user mistake or a bad file raises (volrig.Cancelled and volrig.FileFormatError are VolrigErrors); reported
#: in the UI, never as a traceback. Other exceptions are bugs and propagate.
USER_ERRORS = (volrig.VolrigError, OSError)


def _reported(method):
    """Wraps an operator's execute(self, context) or invoke(self, context, event): user errors become a report."""
    def run(self, context, *event):
        try:
            return method(self, context, *event)
        except volrig.Cancelled:
            self.report({"WARNING"}, "volrig: cancelled")
            return {"CANCELLED"}
        except USER_ERRORS as e:
            self.report({"ERROR"}, f"volrig: {e}")
            return {"CANCELLED"}

    if method.__code__.co_argcount == 3:  # Blender checks the argument count
        def invoke(self, context, event):
            return run(self, context, event)
        return invoke

    def execute(self, context):
        return run(self, context)
    return execute


def _active_volume(context):
    return objects.volume_of(context.active_object)


class _ProgressBar:
    """The window manager's progress bar (0..100) for a with-block; ``steps(spans)`` reports a pipeline's steps
    each on its part of the bar."""

    def __init__(self, context):
        self.wm = context.window_manager

    def __enter__(self):
        self.wm.progress_begin(0, 100)
        return self

    def __exit__(self, *exc):
        self.wm.progress_end()

    def steps(self, spans):
        """A pipeline StepProgress: step name -> its (start, end) span of the bar."""
        def show(step, f):
            start, end = spans[step]
            self.wm.progress_update(start + (end - start) * float(f))
            return True
        return show


def _rigged_volume_of(obj):
    """The volrig Volume object of obj (or a part of it) once it has a rig, else None."""
    vol = objects.volume_of(obj)
    return vol if vol is not None and "RIG" in objects.members(vol) else None


def _rigged_volume(context):
    return _rigged_volume_of(context.active_object)


class _OnVolume:
    """Undoable operators on the active object's volrig volume, offered in the context modes ``modes`` (None: any)
    and, when ``rigged``, once the volume has a rig."""
    bl_options = {"REGISTER", "UNDO"}
    modes = ("OBJECT",)
    rigged = False

    @classmethod
    def poll(cls, context):
        return cls.volume(context) is not None and (cls.modes is None or context.mode in cls.modes)

    @classmethod
    def volume(cls, context):
        return _rigged_volume(context) if cls.rigged else _active_volume(context)

    @_reported
    def execute(self, context):
        return self.run(context, self.volume(context))


def _settings(panel, context):
    """(the volrig settings of the active object's volume, the panel's layout)."""
    return objects.volume_of(context.active_object).volrig, panel.layout


def _props(layout, settings, *names) -> None:
    for name in names:
        layout.prop(settings, name)


def _labelled(layout, settings, *names, text: str = "") -> None:
    """Drop-downs and text fields with their names on the left half (the sidebar's default cuts them to a few
    letters: "Bindi...", "Rigid ..."); ``text`` replaces a single property's name."""
    for name in names:
        split = layout.split(factor=0.45)
        split.label(text=text or settings.bl_rna.properties[name].name)
        split.prop(settings, name, text="")


#: How the notes a user must act on begin (autorig.cpp): no plan fits, or the given up was overruled.
_WARNINGS = ("no body plan fits", "given up overruled")


def _is_warning(text: str) -> bool:
    """Whether a note (or a part of one) holds something the user must act on."""
    return any(w in text for w in _WARNINGS)


def found_lines(found: str, chars: int = 0) -> list:
    """What autorig found (``pipeline.describe_rig``: "humanoid, fit 0.93 (runner-up chains 0.61); note; ..."), as
    the sidebar's (text, icon) lines: kind and fit, the runner-up, then each part of the note on lines of its own,
    wrapped at word boundaries to `chars` characters when given (a sidebar cuts a longer label off)."""
    head, _, note = found.partition("; ")
    head, _, runner_up = head.partition(" (")
    lines = [(head, "INFO")] + ([(runner_up.rstrip(")"), "BLANK1")] if runner_up else [])
    for part in (p for p in note.split("; ") if p):
        lines += wrapped_lines(part, chars, "ERROR" if _is_warning(part) else "BLANK1")
    return lines


def wrapped_lines(text: str, chars: int, icon: str) -> list:
    """`text` as (line, icon) pairs wrapped at words to `chars` characters (whole when 0), `icon` on the first line."""
    lines = textwrap.wrap(text, chars, break_long_words=False) if chars > 0 else [text]
    return [(line, icon if k == 0 else "BLANK1") for k, line in enumerate(lines)]


def sidebar_chars(context) -> int:
    """About how many characters of a label fit beside an icon in the sidebar region drawn now (0: unknown)."""
    region = getattr(context, "region", None)
    if region is None or region.width <= 0:
        return 0
    prefs = getattr(context, "preferences", None)
    scale = (prefs.system.ui_scale if prefs else 0.0) or 1.0  # 0 in the background
    return max(16, int((region.width - 50 * scale) / (6.5 * scale)))


def draw_wrapped(layout, text: str, context=None, icon: str = "NONE") -> None:
    """A label wrapped at words to the sidebar's width (sidebar_chars; whole when `context` is None), its icon on
    the first line: the sidebar cuts a longer label off mid-word."""
    col = layout.column(align=True)
    for line, line_icon in wrapped_lines(text, sidebar_chars(context) if context is not None else 0, icon):
        col.label(text=line, icon=line_icon)


def _draw_found(layout, found: str, context=None) -> None:
    """found_lines drawn in a column, wrapped to the sidebar's width when `context` is given."""
    col = layout.column(align=True)
    for text, icon in found_lines(found, sidebar_chars(context) if context is not None else 0):
        col.label(text=text, icon=icon)


def _found_level(note: str) -> set:
    """The report level of a rig's note: a warning when no body plan fits or the given up was overruled."""
    return {"WARNING"} if _is_warning(note) else {"INFO"}


class _VolrigPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "volrig"

    @classmethod
    def poll(cls, context):
        return objects.volume_of(context.active_object) is not None
