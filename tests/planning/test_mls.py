"""Moving-least-squares transfer between non-matching node sets."""
import numpy as np
import pytest

from dsim.master.planning.mls import transfer_matrix


def edge(count, x0=0.0, x1=0.1, y=0.1):
    return np.column_stack((np.linspace(x0, x1, count), np.full(count, y)))


@pytest.mark.parametrize("support", [1.5, 2.0, 3.0])
def test_rows_are_a_partition_of_unity_reproducing_linear_fields(support):
    fine, coarse = edge(9), edge(5)
    T = transfer_matrix(fine, coarse, support)
    assert T.shape == (9, 5)
    assert np.allclose(T.sum(axis=1), 1.0, atol=1e-13)
    assert np.allclose(T @ coarse, fine, atol=1e-13)  # linear fields, so rigid motion


def test_force_and_moment_carried_across_are_conserved():
    """Forces F on the dependent nodes reach the independent ones as T^T F."""
    fine, coarse = edge(9), edge(5)
    T = transfer_matrix(fine, coarse)
    rng = np.random.default_rng(1)
    forces = rng.normal(size=(9, 2))
    carried = T.T @ forces
    assert np.allclose(carried.sum(axis=0), forces.sum(axis=0), atol=1e-13)

    def moment(points, f):
        return np.sum(points[:, 0] * f[:, 1] - points[:, 1] * f[:, 0])

    assert moment(coarse, carried) == pytest.approx(moment(fine, forces), abs=1e-13)


def test_a_face_in_3d_reproduces_linear_fields():
    grid = np.array([(x, y, 0.5) for x in np.linspace(0, 1, 4) for y in np.linspace(0, 1, 4)])
    finer = np.array([(x, y, 0.5) for x in np.linspace(0, 1, 7) for y in np.linspace(0, 1, 7)])
    T = transfer_matrix(finer, grid, support=2.5)
    field = 3.0 * grid[:, 0] - 2.0 * grid[:, 1] + 1.0
    assert np.allclose(T @ field, 3.0 * finer[:, 0] - 2.0 * finer[:, 1] + 1.0, atol=1e-12)


def test_support_one_on_an_edge_is_the_linear_interpolant():
    T = transfer_matrix(edge(9), edge(5), support=1.0)
    expected = np.zeros((9, 5))
    for p in range(9):
        k, odd = divmod(p, 2)
        expected[p, k] = 0.5 if odd else 1.0
        if odd:
            expected[p, k + 1] = 0.5
    assert np.allclose(T, expected, atol=1e-14)


def test_a_node_seeing_too_few_nodes_widens_its_own_support():
    """A face point on a cell edge sees 2 nodes at support 1; a plane fit needs 3."""
    grid = np.array([(x, y, 0.0) for x in range(3) for y in range(3)], float)
    T = transfer_matrix(np.array([[0.5, 0.0, 0.0], [1.0, 1.0, 0.0]]), grid, support=0.3)
    assert np.allclose(T @ grid, [[0.5, 0.0, 0.0], [1.0, 1.0, 0.0]], atol=1e-13)


def test_too_few_nodes_for_a_fit_is_a_clear_error():
    square = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], float)
    with pytest.raises(ValueError, match="cannot determine a fit"):
        transfer_matrix(np.array([[0.5, 0.5, 0.0]]), square[:2], support=1.0)


def test_non_matching_bar_in_tension_matches_the_one_piece_bar():
    """A bar in tension, split at x = 0.5 into a coarse (5-node cut) and a fine
    (9-node cut) mesh glued by MLS, settles on the one-piece bar's static answer
    (away from the clamped root the stress is uniform, so both meshes are exact
    there and any difference is the transfer's), and the joint carries exactly
    the applied load."""
    from dsim.fmus.elastic.assembly import STEEL
    from dsim.fmus.elastic.core import ElasticBody, PointLoad
    from dsim.fmus.elastic.geometry import in_box, rectangle
    from dsim.master.planning.assembly import glue_cores
    from dsim.master.scene import Joint, MasterSettings

    length, depth, thickness, force = 1.0, 0.1, 0.01, 1e5
    cut = in_box((0.5, 0.0), (0.5, depth))
    root = in_box((0, 0), (0, depth))
    damping = (500.0, 2e-5)  # settle to the static state within the run

    def traction(mesh):
        """Consistent nodal loads of a uniform end traction on linear elements."""
        nodes = np.flatnonzero(np.isclose(mesh.p[0], length))
        nodes = nodes[np.argsort(mesh.p[1, nodes])]
        shares = np.ones(len(nodes))
        shares[[0, -1]] = 0.5
        shares *= force / shares.sum()
        return [PointLoad(tuple(mesh.p[:, n]), "x", constant=f) for n, f in zip(nodes, shares)]

    left = ElasticBody(rectangle(0, 0.5, 0, depth, 0.025), STEEL, thickness=thickness,
                       node_sets={"root": root, "cut": cut}, clamped=["root"], ports=["cut"],
                       rayleigh=damping)
    right_mesh = rectangle(0.5, length, 0, depth, 0.0125)
    right = ElasticBody(right_mesh, STEEL, thickness=thickness, node_sets={"cut": cut},
                        ports=["cut"], loads=traction(right_mesh),
                        probes={"tip": (length, depth / 2)}, rayleigh=damping)
    joint = Joint("j", ("left", "cut"), ("right", "cut"), ("x", "y"), support=2.0)  # smoothing
    gluing = glue_cores({"left": left, "right": right}, [joint],
                        MasterSettings(step=1e-4, tolerance=1e-14))
    assert gluing.layout.size == 2 * 9  # forces live on the finer side's nodes
    for i in range(1500):
        gluing.step(i * 1e-4, 1e-4, i + 1)
    assert gluing.forces[0::2].sum() == pytest.approx(-force, rel=1e-6)  # right cut held back
    whole_mesh = rectangle(0, length, 0, depth, 0.025)
    whole = ElasticBody(whole_mesh, STEEL, thickness=thickness, node_sets={"root": root},
                        clamped=["root"], loads=traction(whole_mesh),
                        probes={"tip": (length, depth / 2)})
    whole.set_static_equilibrium(0.0)
    expected = whole.outputs()["tip.u_x"]
    # MLS is not interpolating: T^T spreads the fine side's nodal forces a little
    # differently from the coarse mesh's consistent loads (total force and moment are
    # exact), which moves the tip by 3.3e-4 of its displacement at support 2
    assert right.outputs()["tip.u_x"] == pytest.approx(expected, rel=1e-3)
