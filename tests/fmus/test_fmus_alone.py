"""Every FMU dsim builds simulates alone with its defaults in another FMI tool (fmpy),
and passes its validation: a user can open any of them without a scene."""
import numpy as np
import pytest

from dsim.build_fmus.build import FMU_SCRIPTS


@pytest.mark.parametrize("name", sorted(FMU_SCRIPTS))
def test_a_built_fmu_validates_and_simulates_alone_with_its_defaults(built, name):
    from fmpy import read_model_description, simulate_fmu
    from fmpy.validation import validate_fmu

    fmu = built["fmus"] / f"{name}.fmu"
    assert fmu.is_file()
    assert validate_fmu(str(fmu)) == []
    outputs = [v.name for v in read_model_description(str(fmu)).modelVariables
               if v.causality == "output"]
    result = simulate_fmu(str(fmu), stop_time=0.02, output_interval=1e-3,
                          output=outputs)
    assert result["time"][-1] == pytest.approx(0.02)
    assert len(result) == 21                  # every communication point, none refused
    for output in outputs:
        assert np.all(np.isfinite(result[output])), output


def test_every_fmu_in_the_build_folder_is_one_the_test_covers(built):
    assert sorted(p.stem for p in built["fmus"].glob("*.fmu")) == sorted(FMU_SCRIPTS)


def test_the_elastic_body_without_a_mesh_file_is_the_built_in_beam():
    """ElasticBody's default body: 1 m x 0.1 m, 20 x 2 quads (21 x 3 nodes), steel
    0.01 m thick: its mass is rho L h t."""
    from dsim.fmus.elastic.body_spec import BodySpec, build_body

    body = build_body(BodySpec())
    assert body.mesh.p.shape == (2, 63)
    assert np.ptp(body.mesh.p, axis=1) == pytest.approx([1.0, 0.1])
    along_x = np.zeros(body.mass.shape[0])
    along_x[body.node_dofs[0]] = 1.0                    # a rigid translation along x
    assert along_x @ (body.mass @ along_x) == pytest.approx(7850.0 * 1.0 * 0.1 * 0.01,
                                                            rel=1e-12)
