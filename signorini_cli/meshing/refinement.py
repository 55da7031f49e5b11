"""Uniform refinement of a tagged mesh: the next level of a nested family, with Γ_C carried over.

dolfinx 0.5.2's refine gives no parent-facet map, so Γ_C is re-found geometrically: a boundary facet
of the refined mesh is CONTACT when its centroid lies in a CONTACT facet of the parent. New vertices
are edge midpoints, so every refined boundary facet lies inside one parent facet (the polygon is kept,
not moved onto a curved boundary: that is what keeps the family nested), and its centroid sits well
inside it (barycentric coordinates >= 1/6). The parent's CONTACT facets are gathered on every rank,
so the result does not depend on how either mesh is partitioned."""
import numpy as np

import dolfinx.mesh

from .domain import CONTACT, domain_of, facet_vertices, tag_facets

INSIDE_TOL = 1e-8  # relative; refined centroids are >= 1/6 inside their parent facet, rounding ~1e-16


def refine(domain):
    """The uniformly refined Domain (every cell split in 2^d); n is its number of cells."""
    parent = domain.mesh
    parent.topology.create_entities(1)  # refine needs the edges
    child = dolfinx.mesh.refine(parent)
    parent_contact = domain.facet_tags.indices[domain.facet_tags.values == CONTACT]
    contact_facets = np.vstack(parent.comm.allgather(facet_vertices(parent, parent_contact)))
    tags = tag_facets(child, lambda boundary: in_simplices(facet_vertices(child, boundary).mean(axis=1),
                                                           contact_facets))
    return domain_of(child, tags, child.topology.index_map(child.topology.dim).size_global)


def in_simplices(points, simplices, tol=INSIDE_TOL):
    """For each point, whether it lies in one of the simplices (m, k+1, 3) of dimension k < 3: within
    tol * diameter of the simplex's affine hull, with barycentric coordinates >= -tol."""
    inside = np.zeros(len(points), dtype=bool)
    if len(points) == 0 or len(simplices) == 0:
        return inside
    from scipy.spatial import cKDTree  # scipy.spatial: 0.3 s of every command's start-up if imported at the top
    centres = simplices.mean(axis=1)
    reach = np.linalg.norm(simplices - centres[:, None], axis=2).max() * (1 + tol)
    candidates = cKDTree(centres).query_ball_point(points, reach)
    point_ids = np.repeat(np.arange(len(points)), [len(c) for c in candidates])
    simplex_ids = np.concatenate([np.asarray(c, dtype=np.int64) for c in candidates])
    if len(simplex_ids) == 0:
        return inside
    origin = simplices[simplex_ids, 0]
    edges = simplices[simplex_ids, 1:] - origin[:, None]                # (n, k, 3)
    w = points[point_ids] - origin
    gram = edges @ edges.transpose(0, 2, 1)
    lam = np.linalg.solve(gram, edges @ w[..., None])[..., 0]           # least-squares barycentrics
    off_hull = np.linalg.norm(w - np.einsum("nk,nkj->nj", lam, edges), axis=1)
    diameter = np.sqrt(gram.diagonal(axis1=1, axis2=2).max(axis=1))
    hit = (lam >= -tol).all(axis=1) & (lam.sum(axis=1) <= 1 + tol) & (off_hull <= tol * diameter)
    inside[point_ids[hit]] = True
    return inside
