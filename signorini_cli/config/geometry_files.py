"""Geometry sources on disk: shipped .geo files, users' .msh files, their named physical groups
(read as text, without gmsh) and the mesh cache's file names."""
import hashlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GEOMETRY_DIR = ROOT / "meshes"  # the shipped geometries: meshes/<name>.geo
CACHE_DIR = ROOT / "meshes" / "cache"  # shipped geometries' meshes (gitignored): one .msh per (geometry, size, hash)
USER_CACHE = "signorini-meshes"  # a user's .geo: its meshes in this folder beside it, not in the tool's checkout
# Bumped when the meshing options in geometries.generate change, so old cache entries are not reused.
MESHING_VERSION = "1"

_GEO_GROUP = re.compile(r'Physical\s+(Point|Curve|Line|Surface|Volume)\s*\(\s*"([^"]+)"')
_GEO_DIMS = {"Point": 0, "Curve": 1, "Line": 1, "Surface": 2, "Volume": 3}
_MSH_NAME = re.compile(rb'^\s*(\d+)\s+(\d+)\s+"([^"]*)"\s*$')


def shipped_geometries():
    """Names of the geometries under meshes/ (the stems of their .geo files)."""
    return tuple(sorted(p.stem for p in GEOMETRY_DIR.glob("*.geo")))


def geometry_path(name):
    """The .geo file of a shipped geometry name, or the path itself when it ends in .geo."""
    return Path(name) if name.endswith(".geo") else GEOMETRY_DIR / f"{name}.geo"


def physical_groups(path):
    """{name: dimension} of the named physical groups of a .geo (its `Physical ...("name")` lines)
    or a .msh file (its $PhysicalNames section)."""
    path = Path(path)
    if path.suffix == ".geo":
        # a binary file is no .geo: read as text it names no group, which the caller reports
        return {name: _GEO_DIMS[kind] for kind, name in _GEO_GROUP.findall(path.read_text(errors="replace"))}
    return _msh_physical_names(path.read_bytes())


def _msh_physical_names(data):
    # $PhysicalNames is ASCII in both the text and the binary .msh formats (2.2 and 4.1)
    start, end = data.find(b"$PhysicalNames"), data.find(b"$EndPhysicalNames")
    if start < 0 or end < 0:
        return {}
    groups = {}
    for line in data[start:end].splitlines()[2:]:
        match = _MSH_NAME.match(line)
        if match:
            groups[match.group(3).decode()] = int(match.group(1))
    return groups


def source_hash(paths):
    """sha256 (hex, 16 digits) of the files' contents: a changed geometry or mesh file changes it."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(Path(path).read_bytes())
    return digest.hexdigest()[:16]


def cache_folder(geo, cache=""):
    """Where the meshes of `geo` are kept: `cache` when the config names one, else meshes/cache for a
    shipped geometry and signorini-meshes/ beside a user's .geo (their meshes stay with their geometry)."""
    if cache:
        return Path(cache)
    geo = Path(geo).resolve()
    return CACHE_DIR if geo.parent == GEOMETRY_DIR.resolve() else geo.parent / USER_CACHE


def cache_file(cache_dir, geo, size):
    """The cache entry of `geo` meshed at `size` in `cache_dir` (empty: cache_folder's choice): named by
    geometry and size, keyed by a hash of the .geo text, so a changed geometry gets a new entry."""
    digest = hashlib.sha256(Path(geo).read_bytes())
    digest.update(f"size={size!r};meshing={MESHING_VERSION}".encode())
    return cache_folder(geo, cache_dir) / f"{Path(geo).stem}-h{size:g}-{digest.hexdigest()[:16]}.msh"


def msh_node_count(path, chunk=1 << 20):
    """The number of nodes a .msh file (2.2 or 4.1, text or binary) declares in its $Nodes header, read
    without its node or element data (a few chunks up to $Nodes); None when there is no such header."""
    with open(path, "rb") as f:
        head = f.read(max(chunk, 256))  # $MeshFormat's three numbers come first
        fmt = re.match(rb"\$MeshFormat\s+(\d+)\.?\d*\s+(\d)\s+(\d)", head)
        if fmt is None:
            return None
        while (at := head.find(b"$Nodes\n")) < 0 or len(head) < at + 80:
            more = f.read(chunk)
            if not more:
                break
            head = head[-80:] + more if at < 0 else head + more  # keep a header cut between two chunks
    if at < 0:
        return None
    body = head[at + len(b"$Nodes\n"):]
    version, binary, size = int(fmt.group(1)), fmt.group(2) == b"1", int(fmt.group(3))
    if version >= 4 and binary:  # numEntityBlocks numNodes minNodeTag maxNodeTag as size_t, little-endian
        return int.from_bytes(body[size:2 * size], "little")
    numbers = body.split(b"\n", 1)[0].split()  # 4.1 text: blocks, nodes, min, max; 2.2: nodes alone
    return int(numbers[1] if version >= 4 else numbers[0]) if numbers else None
