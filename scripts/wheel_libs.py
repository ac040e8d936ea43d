"""Makes a compiled module self-contained, as auditwheel repairs a wheel (Debian has no auditwheel; this uses only
binutils' readelf and strip and Debian's patchelf).

Every shared library the module needs, the closure of the DT_NEEDED entries, is found in the Debian root the
module was built in (``/`` for the machine's own Python, the cached Debian 13 root of scripts/trixie_root for
Python 3.13 on a Debian 12 machine): the lookup follows the loader's order (the object's RUNPATH, then
/etc/ld.so.conf.d, then the default directories) and resolves symbolic links inside that root, so a module built
for Debian 13 gets Debian 13's libraries even when this runs on Debian 12. All of them but the system libraries of
the manylinux policy (glibc: libc, libm, libdl, librt, libpthread, ld-linux...; libstdc++ and libgcc_s) are copied
into ``volrig.libs/`` beside the package, stripped of what linking does not need (``strip --strip-unneeded``),
renamed with the first 8 hex digits of their sha256 (``libtbb.so.12`` -> ``libtbb-1a2b3c4d.so.12``: a program that
already loaded its own libtbb.so.12, Blender does, keeps it and volrig gets its own copy), their SONAME and every
DT_NEEDED entry naming a bundled library rewritten to the new names, and their RUNPATH set to ``$ORIGIN``; the
module's RUNPATH becomes ``$ORIGIN/../volrig.libs``.

    python3 scripts/wheel_libs.py MODULE.so [ROOT]   # lists the closure: NEEDED name, file in ROOT, bundled or not
"""
import glob
import hashlib
import os
import re
import shutil
import subprocess
import sys

LIBS_DIR = "volrig.libs"

# The manylinux policy's system libraries (PEP 600 / auditwheel's lib_whitelist, minus the X11/GL/glib ones volrig
# never links): glibc's, libstdc++ and libgcc_s. Everything else is bundled.
SYSTEM = {
    "libc.so.6", "libm.so.6", "libdl.so.2", "librt.so.1", "libpthread.so.0", "libresolv.so.2", "libutil.so.1",
    "libnsl.so.1", "libcrypt.so.1", "ld-linux-x86-64.so.2", "libstdc++.so.6", "libgcc_s.so.1",
}

DEFAULT_DIRS = ["/lib/x86_64-linux-gnu", "/usr/lib/x86_64-linux-gnu", "/lib64", "/usr/lib64", "/lib", "/usr/lib"]


def in_root(root: str, path: str) -> str:
    """The host path of ``path`` as seen inside ``root``, every symbolic link followed inside the root (an
    absolute link target is taken relative to the root, not to this machine)."""
    parts = [p for p in path.split("/") if p]
    resolved = []
    hops = 0
    while parts:
        p = parts.pop(0)
        if p == ".":
            continue
        if p == "..":
            if resolved:
                resolved.pop()
            continue
        host = os.path.join(root, *resolved, p)
        if os.path.islink(host):
            hops += 1
            if hops > 40:
                raise OSError(f"too many symbolic links under {root}: {path}")
            target = os.readlink(host)
            if target.startswith("/"):
                resolved = []
            parts = [q for q in target.split("/") if q] + parts
            continue
        resolved.append(p)
    return os.path.join(root, *resolved)


def dynamic(path: str):
    """(SONAME or None, [NEEDED...], [RUNPATH or RPATH entries]) of an ELF file, from `readelf -d`."""
    out = subprocess.run(["readelf", "-d", "-W", path], capture_output=True, text=True, check=True).stdout
    soname, needed, runpath = None, [], []
    for kind, value in re.findall(r"\((NEEDED|SONAME|RUNPATH|RPATH)\)\s+[^\[]*\[([^\]]*)\]", out):
        if kind == "NEEDED":
            needed.append(value)
        elif kind == "SONAME":
            soname = value
        else:
            runpath += [d for d in value.split(":") if d]
    return soname, needed, runpath


def _conf_dirs(root: str, conf: str = "/etc/ld.so.conf", seen=None) -> list:
    """The directories /etc/ld.so.conf (and what it includes) lists inside ``root``."""
    seen = set() if seen is None else seen
    dirs = []
    host = in_root(root, conf)
    if host in seen or not os.path.isfile(host):
        return dirs
    seen.add(host)
    for line in open(host, errors="replace"):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("include "):
            for pattern in line.split()[1:]:
                pattern = pattern if pattern.startswith("/") else os.path.join(os.path.dirname(conf), pattern)
                for f in sorted(glob.glob(in_root(root, os.path.dirname(pattern)) + "/" +
                                          os.path.basename(pattern))):
                    dirs += _conf_dirs(root, os.path.join(os.path.dirname(pattern), os.path.basename(f)), seen)
        else:
            dirs.append(line)
    return dirs


def find(root: str, name: str, origin_dir: str, runpath: list, conf: list) -> str:
    """The host path of the library ``name`` that the loader in ``root`` would take for an object in
    ``origin_dir`` (a path inside the root) with ``runpath``."""
    dirs = [d.replace("$ORIGIN", origin_dir).replace("${ORIGIN}", origin_dir) for d in runpath] + conf + DEFAULT_DIRS
    for d in dirs:
        host = in_root(root, os.path.join(d, name))
        if os.path.isfile(host):
            return host
    raise FileNotFoundError(f"{name} not found in {root} (searched {', '.join(dirs)})")


def closure(module: str, root: str = "/") -> dict:
    """{NEEDED name: host path of the file in ``root``} for every library ``module`` needs, recursively; the
    system libraries (SYSTEM) are listed (to check they exist in the root) but not followed."""
    conf = _conf_dirs(root)
    found = {}
    todo = [(module, "/volrig-module")]  # (host path, its directory as seen inside the root)
    while todo:
        path, inside_dir = todo.pop()
        _, needed, runpath = dynamic(path)
        for name in needed:
            if name in found:
                continue
            host = find(root, name, inside_dir, runpath, conf)
            found[name] = host
            if name not in SYSTEM:
                rel = os.path.relpath(host, os.path.abspath(root))
                todo.append((host, "/" + os.path.dirname(rel)))
    return found


def hashed_name(name: str, data: bytes) -> str:
    """auditwheel's naming: libfoo.so.1.2 -> libfoo-<8 hex digits of sha256>.so.1.2."""
    base, dot, rest = name.partition(".so")
    return f"{base}-{hashlib.sha256(data).hexdigest()[:8]}{dot}{rest}"


def bundle(module: str, root: str, work: str) -> tuple:
    """Copies ``module`` into ``work`` with its non-system libraries in ``work``/volrig.libs, renamed, stripped and
    patched (see the module's doc). Returns (patched module path, [bundled library paths])."""
    libs = os.path.join(work, LIBS_DIR)
    os.makedirs(libs, exist_ok=True)
    deps = {n: p for n, p in closure(module, root).items() if n not in SYSTEM}
    rename = {}
    for name, host in sorted(deps.items()):
        data = open(host, "rb").read()
        rename[name] = hashed_name(name, data)
    out = os.path.join(work, os.path.basename(module))
    shutil.copyfile(module, out)
    copies = []
    for name, host in sorted(deps.items()):
        dst = os.path.join(libs, rename[name])
        shutil.copyfile(host, dst)
        os.chmod(dst, 0o755)
        subprocess.run(["strip", "--strip-unneeded", dst], check=True)
        copies.append(dst)
    for path in [out] + copies:
        # One kind of change per patchelf run, then a check: Debian 12's patchelf 0.14 garbles the string table when
        # one run makes two kinds of change (e.g. --set-soname with --replace-needed gave a SONAME of the replaced
        # name), and the version needs are checked too (a wrong name there stops the loader). Each run copies
        # .dynstr into a new segment: libopenvdb's 22 MB of C++ symbol names make it grow by that each time (57 to
        # 125 MB; patchelf 0.18 in one run grows it as much; the wheel, compressed, by little).
        _, needed, _ = dynamic(path)
        replace = [a for n in needed if n in rename for a in ("--replace-needed", n, rename[n])]
        if replace:
            subprocess.run(["patchelf"] + replace + [path], check=True)
        if path != out:
            subprocess.run(["patchelf", "--set-soname", os.path.basename(path), path], check=True)
        # --force-rpath, as auditwheel does: DT_RPATH, not DT_RUNPATH, is searched before LD_LIBRARY_PATH (a
        # user's LD_LIBRARY_PATH cannot swap a bundled library for another build) and serves the libraries that
        # the object's own dependencies need too.
        rpath = "$ORIGIN/../" + LIBS_DIR if path == out else "$ORIGIN"
        subprocess.run(["patchelf", "--force-rpath", "--set-rpath", rpath, path], check=True)
        soname, got, runpath = dynamic(path)
        want = [rename.get(n, n) for n in needed]
        versioned = version_files(path)  # the loader matches symbol versions to libraries by these names
        if got != want or runpath != [rpath] or (path != out and soname != os.path.basename(path)) or \
                not set(versioned) <= set(got):
            raise RuntimeError(f"patchelf left {path} wrong: SONAME {soname}, NEEDED {got}, RPATH {runpath}, "
                               f"version needs of {versioned}")
    return out, copies


def version_files(path: str) -> list:
    """The library names of an ELF file's version needs (.gnu.version_r), from `readelf -V`."""
    out = subprocess.run(["readelf", "-V", "-W", path], capture_output=True, text=True, check=True).stdout
    return re.findall(r"Version: \d+\s+File: (\S+)", out)


def glibc_needed(paths) -> tuple:
    """(highest GLIBC_2.x minor, highest GLIBCXX_3.4.x patch) the files' symbol versions require."""
    glibc, glibcxx = 0, 0
    for p in paths:
        out = subprocess.run(["readelf", "-V", "-W", p], capture_output=True, text=True, check=True).stdout
        for m in re.findall(r"Name: GLIBC_2\.(\d+)", out):
            glibc = max(glibc, int(m))
        for m in re.findall(r"Name: GLIBCXX_3\.4\.(\d+)", out):
            glibcxx = max(glibcxx, int(m))
    return glibc, glibcxx


def main() -> int:
    module, root = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else "/")
    for name, host in sorted(closure(module, root).items()):
        print(f"{name:36} {host}  {'system' if name in SYSTEM else 'bundled'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
