"""Fields for ParaView and meshio (output.fields: true): u_h, its error and the Γ_C contact indicator, XDMF
per level."""
import xml.etree.ElementTree as ET

import numpy as np

from ..meshing.meshes import CONTACT
from ..system import files


def write(folder, index, domain, u_h, u_exact):
    """fields/level_NN.xdmf (+ .h5) in `folder`: the mesh with its boundary tags (1 = Γ_C, 2 = Γ_D),
    u_h, error = u_h − u_ex at the nodes (manufactured scenes only) and contact = 1 where u_h > 0 on Γ_C."""
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
        xdmf.write_function(contact_indicator(u_h, domain))
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
