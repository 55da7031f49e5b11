"""gmsh geometries: physical groups tag Γ_C (checked against exact lengths and areas within the polygonal
error), the .msh cache hits and misses, .msh files read back, and one study identical on 1 and 2 ranks."""
import math
import os
import shutil
import subprocess
import sys
from itertools import combinations

import numpy as np
import pytest
import ufl
import yaml
from mpi4py import MPI

from dolfinx import fem
from signorini_cli import config, studies
from signorini_cli.app import cli
from signorini_cli.config import geometry_files
from signorini_cli.meshing import geometries, meshes, refinement
from signorini_cli.meshing.meshes import CONTACT, DIRICHLET
from conftest import BASE, merge

ROUND_OFF = 1e-12  # relative: sums of a few thousand facet measures, each exact to ~1e-16


@pytest.fixture
def shared_tmp(tmp_path):
    """rank 0's tmp_path on every rank (files written by rank 0 are read by all)."""
    return MPI.COMM_WORLD.bcast(tmp_path, root=0)


def mesh_config(cache, contact="contact", **mesh):
    """A validated config with mesh {kind: gmsh, cache, **mesh} and Γ_C = the physical group `contact`."""
    raw = merge(BASE, {"contact": contact, "dimension": None})
    raw["mesh"] = dict({"kind": "gmsh", "cache": str(cache)}, **mesh)  # replaced: no unit_square keys
    return config.loads(yaml.safe_dump(raw))


def build(cache, geometry, size, comm=MPI.COMM_WORLD):
    cfg = mesh_config(cache, geometry=geometry, sizes=[size])
    return meshes.build(cfg.mesh, cfg.contact, size, comm)


def measure(domain, tag):
    ds = ufl.Measure("ds", domain=domain.mesh, subdomain_data=domain.facet_tags)(tag)
    form = fem.form(fem.Constant(domain.mesh, 1.0) * ds)
    return domain.mesh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)


def tagged_vertices(domain, tag):
    """(facets, d, 3) vertex coordinates of this rank's facets with `tag`."""
    return refinement.facet_vertices(domain.mesh, domain.facet_tags.indices[domain.facet_tags.values == tag])


def allmax(values, comm=MPI.COMM_WORLD):
    return comm.allreduce(float(np.max(values)) if np.size(values) else 0.0, op=MPI.MAX)


# --- physical groups tag Γ_C and Γ_D ---------------------------------------------------------------

@pytest.mark.parametrize("geometry, size, gamma_c, gamma_d", [
    pytest.param("unit_square", 0.25, 1.0, 3.0, id="square"),
    pytest.param("l_shape", 0.25, 1.0, 7.0, id="l-shape"),
    pytest.param("unit_cube", 0.5, 1.0, 5.0, id="cube"),
])
def test_tagging_flat_measures_exact(tmp_path, geometry, size, gamma_c, gamma_d):
    domain = build(tmp_path, geometry, size)
    # straight edges and planar faces are tiled exactly by the facets: only round-off remains
    assert measure(domain, CONTACT) == pytest.approx(gamma_c, rel=ROUND_OFF)
    assert measure(domain, DIRICHLET) == pytest.approx(gamma_d, rel=ROUND_OFF)


def test_tagging_half_disk_arc_length(tmp_path):
    domain = build(tmp_path, "half_disk", 0.2)
    arc, diameter = tagged_vertices(domain, CONTACT), tagged_vertices(domain, DIRICHLET)
    # Γ_C is the group, not a coordinate test: its vertices are on the unit circle, Γ_D's on y = 0
    assert allmax(abs(np.linalg.norm(arc, axis=2) - 1)) < 1e-14
    assert allmax(abs(diameter[:, :, 1])) < 1e-14
    # A chord c subtends theta = 2 asin(c/2) of the unit circle and is shorter than its arc by
    # theta - 2 sin(theta/2) <= theta^3/24, so 0 <= pi - |Γ_C,h| <= pi theta_max^2 / 24 (the polygonal error).
    theta = 2 * math.asin(allmax(np.linalg.norm(arc[:, 1] - arc[:, 0], axis=1)) / 2)
    deficit = math.pi - measure(domain, CONTACT)
    assert -ROUND_OFF <= deficit <= math.pi * theta**2 / 24
    assert measure(domain, DIRICHLET) == pytest.approx(2.0, rel=ROUND_OFF)


def test_tagging_half_ball_hemisphere_area(tmp_path):
    domain = build(tmp_path, "half_ball", 0.3)
    sphere, disk = tagged_vertices(domain, CONTACT), tagged_vertices(domain, DIRICHLET)
    assert allmax(abs(np.linalg.norm(sphere, axis=2) - 1)) < 1e-14
    assert allmax(abs(disk[:, :, 2])) < 1e-14
    # A flat triangle T inscribed in the unit sphere, circumradius rho, lies at distance d = sqrt(1 - rho^2)
    # from the centre; radial projection maps it onto a spherical triangle S with Jacobian d/r^3, r in
    # [d, 1], so d|T| <= |S| <= |T|/d^2. The S tile the hemisphere: sum d|T| <= 2 pi <= sum |T|/d^2.
    a, b, c = (np.linalg.norm(sphere[:, i] - sphere[:, j], axis=1) for i, j in ((0, 1), (1, 2), (2, 0)))
    area = np.linalg.norm(np.cross(sphere[:, 1] - sphere[:, 0], sphere[:, 2] - sphere[:, 0]), axis=1) / 2
    d = np.sqrt(1 - (a * b * c / (4 * area)) ** 2)
    assert np.sum(d * area) * (1 - ROUND_OFF) <= 2 * math.pi <= np.sum(area / d**2) * (1 + ROUND_OFF)
    assert measure(domain, CONTACT) == pytest.approx(np.sum(area), rel=ROUND_OFF)  # Γ_C,h is those T
    # the flat disk is an inscribed polygon: pi (1 - theta^2/6) <= |Γ_D,h| <= pi (sector minus triangle)
    theta = 2 * math.asin(allmax([np.linalg.norm(disk[:, i] - disk[:, j], axis=1)
                                  for i, j in combinations(range(3), 2)]) / 2)
    assert math.pi * (1 - theta**2 / 6) <= measure(domain, DIRICHLET) <= math.pi * (1 + ROUND_OFF)


def test_refinement_keeps_tagged_measures(tmp_path):
    base = build(tmp_path, "half_disk", 0.3)
    once = refinement.refine(base)
    twice = refinement.refine(once)
    # nested: the refined boundary stays on the base polygon, so Γ_C and Γ_D keep their measures
    for tag in (CONTACT, DIRICHLET):
        assert measure(twice, tag) == pytest.approx(measure(base, tag), rel=ROUND_OFF)
    assert twice.n == 16 * base.n  # 2-D: every cell split in four, twice


@pytest.mark.parametrize("mesh, nested", [
    pytest.param({"sizes": [0.3], "refine": "uniform", "refinements": [0, 1]}, True, id="nested-family"),
    pytest.param({"sizes": [0.3, 0.2]}, False, id="meshed-one-by-one"),
])
def test_reference_domain_refines_finest_level(tmp_path, mesh, nested):
    cfg = mesh_config(tmp_path, geometry="half_disk", **mesh)
    finest = meshes.build(cfg.mesh, cfg.contact, cfg.mesh.levels[-1])
    reference, is_nested = meshes.reference_domain(cfg.mesh, cfg.contact, 1)
    assert is_nested == nested and reference.n == 4 * finest.n  # 2-D: one refinement, four times the cells
    assert measure(reference, CONTACT) == pytest.approx(measure(finest, CONTACT), rel=ROUND_OFF)


def test_level_columns_half_disk(tmp_path):
    cfg = mesh_config(tmp_path, geometry="half_disk", sizes=[0.3], refine="uniform", refinements=[0, 1])
    coarse, fine = (meshes.build(cfg.mesh, cfg.contact, k) for k in (0, 1))
    assert list(coarse.columns) == ["target_size", "h_min", "gamma_c_measure", "gamma_c_quasi_uniformity"]
    assert fine.columns["target_size"] == 0.15 and fine.columns["h_min"] == fine.h_min <= fine.h
    # half-disk: gmsh divides the arc into equal chords, so the trace mesh is uniform to round-off
    # (measured 1 + 6e-9: gmsh places arc nodes by its own parametrisation tolerance)
    assert coarse.columns["gamma_c_quasi_uniformity"] == pytest.approx(1.0, abs=1e-6)


# --- the cache ---------------------------------------------------------------------------------------

def test_cache_hit_miss_and_invalidation(tmp_path):
    geo = tmp_path / "square.geo"
    shutil.copy(geometry_files.geometry_path("unit_square"), geo)
    cache = tmp_path / "cache"
    path, generated = geometries.mesh_file(geo, 0.5, 2, cache)
    assert generated and path.exists() and path.parent == cache
    stamp = path.stat().st_mtime_ns
    again, generated = geometries.mesh_file(geo, 0.5, 2, cache)
    assert (again, generated) == (path, False) and path.stat().st_mtime_ns == stamp  # hit: not rewritten
    other_size, generated = geometries.mesh_file(geo, 0.25, 2, cache)
    assert generated and other_size != path
    geo.write_text(geo.read_text().replace("Point(3) = {1, 1, 0};", "Point(3) = {1, 2, 0};"))
    changed, generated = geometries.mesh_file(geo, 0.5, 2, cache)
    assert generated and changed != path  # a changed geometry file is a miss, never its stale mesh


def test_cache_gmsh_failure_raises(tmp_path):
    geo = tmp_path / "bad.geo"
    geo.write_text("Point(1) = {0, 0, 0;\n")
    with pytest.raises(geometries.GeometryError, match="syntax error"):
        geometries.mesh_file(geo, 0.5, 2, tmp_path)


def test_gmsh_failure_is_bad_input_before_any_level(tmp_path, capsys):
    (tmp_path / "bad.geo").write_text('Point(1) = {0, 0, 0;\nPhysical Curve("contact") = {1};\n'
                                      'Physical Surface("domain") = {1};\n')
    raw = merge(BASE, {"contact": "contact", "dimension": None, "output": {"dir": str(tmp_path / "out")}})
    raw["mesh"] = {"kind": "gmsh", "geometry": str(tmp_path / "bad.geo"), "sizes": [0.5], "cache": str(tmp_path)}
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert cli.main(["run", str(path), "--quiet"]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.startswith(f"signorini: error: {path}: mesh.geometry: meshing ") and "syntax error" in err
    assert err.count("\n") == 1 and not (tmp_path / "out").exists()


# --- .msh files --------------------------------------------------------------------------------------

def convert(source, target, version):
    """Write the mesh file `source` again in .msh format `version` (ASCII), as another tool would."""
    gmsh = geometries._import_gmsh()
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(source))
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.write(str(target))
    finally:
        geometries._finalize(gmsh)


@pytest.mark.parametrize("version", [4.1, 2.2])
def test_msh_round_trip_matches_generated(tmp_path, version):
    generated = mesh_config(tmp_path, geometry="half_disk", sizes=[0.3])
    cached, _ = geometries.mesh_file(geometry_files.geometry_path("half_disk"), 0.3, 2, tmp_path)
    copy = tmp_path / f"user-{version}.msh"
    convert(cached, copy, version)
    assert geometry_files.physical_groups(copy) == {"contact": 1, "dirichlet": 1, "domain": 2}
    from_file = mesh_config(tmp_path, kind="file", path=str(copy))
    a, b = (studies.run_study(cfg, comm=MPI.COMM_SELF)[0] for cfg in (generated, from_file))
    # the same mesh through either path: same cells, h and Γ_C, and the same solution to solver tolerance
    assert (a.n, a.dofs, a.h) == (b.n, b.dofs, b.h)
    assert b.extra["gamma_c_measure"] == pytest.approx(a.extra["gamma_c_measure"], rel=ROUND_OFF)
    for norm in ("L2", "H1"):
        assert b.errors[norm] == pytest.approx(a.errors[norm], rel=1e-10)  # SNES rtol 1e-10


def test_physical_groups_of_geo_and_binary_msh(tmp_path):
    assert geometry_files.physical_groups(geometry_files.geometry_path("half_ball")) == {
        "contact": 2, "dirichlet": 2, "domain": 3}
    binary, _ = geometries.mesh_file(geometry_files.geometry_path("l_shape"), 0.5, 2, tmp_path)
    assert b"\0" in binary.read_bytes()  # the cache writes binary .msh
    assert geometry_files.physical_groups(binary) == {"contact": 1, "dirichlet": 1, "domain": 2}


def test_file_without_contact_group_is_config_error(tmp_path):
    with pytest.raises(config.ConfigError, match="^contact: 'bottom' is not one of inner_arc, outer_arc"):
        mesh_config(tmp_path, kind="file", path=str(geometry_files.GEOMETRY_DIR / "examples/quarter_annulus.msh"),
                    contact="bottom")


# --- gmsh stays out of built-in meshes; MPI ---------------------------------------------------------

def test_builtin_mesh_does_not_import_gmsh(tmp_path):
    script = ("import sys, yaml; from mpi4py import MPI; from signorini_cli import config, studies; "
              f"cfg = config.loads(yaml.safe_dump({dict(BASE, mesh={'kind': 'unit_square', 'refinements': [2]})!r})); "
              "studies.run_study(cfg, comm=MPI.COMM_SELF); print('gmsh' in sys.modules)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert out.stdout.strip() == "False", out.stderr


@pytest.mark.mpi
@pytest.mark.parametrize("mesh", [
    pytest.param({"geometry": "half_disk", "sizes": [0.3, 0.15]}, id="half-disk-sizes"),
    pytest.param({"geometry": "half_disk", "sizes": [0.3], "refine": "uniform", "refinements": [0, 1]},
                 id="half-disk-nested"),
])
def test_two_ranks_match_one_gmsh(shared_tmp, mesh):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    cfg = mesh_config(shared_tmp / "cache", **mesh)
    parallel = studies.run_study(cfg, comm=comm)
    serial = studies.run_study(cfg, comm=MPI.COMM_SELF)  # every rank solves the whole problem alone
    for p, s in zip(parallel, serial):
        assert p.outcome.converged and s.outcome.converged
        assert (p.n, p.dofs) == (s.n, s.dofs) and p.h == pytest.approx(s.h, rel=1e-14)
        assert p.extra == pytest.approx(s.extra, rel=ROUND_OFF)
        for norm in ("L2", "H1"):
            assert p.errors[norm] == pytest.approx(s.errors[norm], rel=1e-8)  # issue 3's parallel tolerance
