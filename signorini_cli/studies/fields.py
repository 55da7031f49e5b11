"""Fields for ParaView and meshio (output.fields: true), XDMF per level: u_h, its error and the Γ_C contact
indicator; for elasticity u_h, its error, the cellwise stress, its von Mises value and the Γ_C contact pressure,
with the exact fields beside them on manufactured scenes."""
import xml.etree.ElementTree as ET

import numpy as np

from ..meshing.meshes import CONTACT
from ..system import files


def write(folder, index, domain, u_h, u_exact, elastic=None):
    """fields/level_NN.xdmf (+ .h5) in `folder`: the mesh with its boundary tags (1 = Γ_C, 2 = Γ_D),
    u_h, error = u_h − u_ex at the nodes (manufactured scenes only) and contact = 1 where u_h > 0 on Γ_C;
    `elastic` (cfg, forms, ε): the elastic fields of elastic_fields instead of the contact indicator."""
    from dolfinx import io
    msh = u_h.function_space.mesh
    path = folder / "fields" / f"level_{index:02d}.xdmf"
    path.parent.mkdir(parents=True, exist_ok=True)  # every rank: exist_ok makes the race harmless
    msh.comm.barrier()
    with files.library_writes(path), io.XDMFFile(msh.comm, str(path), "w") as xdmf:  # a full disk: OSError
        xdmf.write_mesh(msh)
        domain.facet_tags.name = "boundary"
        xdmf.write_meshtags(domain.facet_tags)
        xdmf.write_function(u_h)
        if u_exact is not None:
            xdmf.write_function(nodal_error(u_h, u_exact))
        extra = elastic_fields(*elastic, u_h) if elastic is not None else [contact_indicator(u_h, domain)]
        for function in extra:
            xdmf.write_function(function)
    if msh.comm.rank == 0:
        one_grid(path)
    msh.comm.barrier()
    return path


XI = "{http://www.w3.org/2001/XInclude}include"


def one_grid(path):
    """Rewrite dolfinx's XDMF (a mesh grid, a tag grid and a temporal collection per function) as one
    grid holding every function as a node attribute, which ParaView and meshio both read; the boundary
    tags go to <name>_boundary.xdmf with the mesh's geometry written out (same .h5 file)."""
    ET.register_namespace("xi", "http://www.w3.org/2001/XInclude")
    tree = ET.parse(path)
    domain = tree.getroot().find("Domain")
    grids = domain.findall("Grid")
    mesh, boundary = grids[0], next(g for g in grids if g.get("Name") == "boundary")
    for collection in grids[1:]:
        if collection.get("GridType") == "Collection":
            mesh.extend(collection.find("Grid").findall("Attribute"))
        domain.remove(collection)
    tree.write(path, xml_declaration=True, encoding="utf-8")
    include = boundary.find(XI)
    boundary.insert(list(boundary).index(include), mesh.find("Geometry"))
    boundary.remove(include)
    domain[:] = [boundary]
    tree.write(path.with_name(f"{path.stem}_boundary.xdmf"), xml_declaration=True, encoding="utf-8")


def nodal_error(u_h, u_exact):
    """u_h − I_h u_ex in the P1 space of u_h (XDMF stores P1 values at the mesh nodes)."""
    from dolfinx import fem
    V = u_h.function_space
    error = fem.Function(V, name="error")
    error.interpolate(fem.Expression(u_exact, V.element.interpolation_points()))
    error.x.array[:] = u_h.x.array - error.x.array
    return error


def contact_indicator(u_h, domain):
    """1 at the Γ_C nodes where u_h > 0 (the discrete contact set, where [u_h]_+^α acts), 0 elsewhere."""
    from dolfinx import fem
    V = u_h.function_space
    facets = domain.facet_tags.indices[domain.facet_tags.values == CONTACT]
    dofs = fem.locate_dofs_topological(V, domain.mesh.topology.dim - 1, facets)
    contact = fem.Function(V, name="contact")
    contact.x.array[dofs] = np.where(u_h.x.array[dofs] > 0, 1.0, 0.0)
    return contact


def elastic_fields(cfg, forms, eps_value, u_h):
    """sigma and von_mises of u_h (constant on each cell for P1: DG0, exact), pressure = (1/ε)[u_h·n − g0]_+^α
    at the Γ_C nodes (0 elsewhere); with u_ex: u_exact (nodal), sigma_exact and von_mises_exact at the cells'
    midpoints, pressure_exact = (1/ε)[u_ex·n − g0]_+^α at the Γ_C nodes."""
    from ..problems import elasticity
    term = forms.gap.term
    found = [cellwise(elasticity.stress(cfg, u_h), "sigma", u_h), cellwise(elasticity.von_mises(cfg, u_h),
                                                                          "von_mises", u_h),
             on_contact_nodes(term, elasticity.pressure_values(cfg, term, eps_value), "pressure")]
    if forms.u_exact is None:
        return found
    u_ex = nodal(forms.u_exact, u_h.function_space, "u_exact")
    return found + [u_ex, cellwise(elasticity.stress(cfg, forms.u_exact), "sigma_exact", u_h),
                    cellwise(elasticity.von_mises(cfg, forms.u_exact), "von_mises_exact", u_h),
                    on_contact_nodes(term, elasticity.pressure_values(cfg, term, eps_value, u_exact=True),
                                     "pressure_exact")]


def cellwise(expression, name, u_h):
    """The UFL `expression` at each cell's midpoint, as a DG0 function (scalar or tensor)."""
    from dolfinx import fem
    shape = expression.ufl_shape
    element = ("DG", 0) if not shape else None
    msh = u_h.function_space.mesh
    space = fem.FunctionSpace(msh, element) if element else fem.TensorFunctionSpace(msh, ("DG", 0), shape=shape)
    function = fem.Function(space, name=name)
    function.interpolate(fem.Expression(expression, space.element.interpolation_points()))
    return function


def nodal(expression, V, name):
    """The UFL `expression` interpolated in V (its values at the nodes)."""
    from dolfinx import fem
    function = fem.Function(V, name=name)
    function.interpolate(fem.Expression(expression, V.element.interpolation_points()))
    return function


def on_contact_nodes(term, values, name):
    """A scalar P1 function with `values` (facets, vertices) at the Γ_C facets' vertices (a vertex's
    facets averaged: they differ where the normal jumps), 0 elsewhere."""
    from ..problems import elasticity
    total, count = elasticity.on_vertices(term, values)
    total.name = name
    touched = count.x.array > 0
    total.x.array[touched] /= count.x.array[touched]
    return total
