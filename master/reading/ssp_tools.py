"""The macro step other tools write into an SSD, read when dsim's own ``glue:Master``
gives none: a scene saved by OMSimulator or the Open Simulation Platform then runs
with the step its author chose, not dsim's default.

* OMSimulator: ``ssc:Annotation type="org.openmodelica"`` holding
  ``oms:SimulationInformation`` / ``oms:FixedStepMaster stepSize="..."`` (on the root
  system);
* OSP (libcosim): ``ssc:Annotation type="com.opensimulationplatform"`` holding
  ``osp:Algorithm`` / ``osp:FixedStepAlgorithm baseStepSize="..."`` (on the
  DefaultExperiment); its predecessor cse-core: ``type="org.open-simulation-platform"``
  with ``osp:SimulationInformation`` / ``osp:FixedStepMaster stepSize="..."`` (on the
  root system).  Checked against those tools' own parsers and test files.

Elements are matched by local name under the annotation of the tool's type, so a
namespace URI that differs between a tool's versions does not hide the step.
Precedence (dsim.master.api): ``--step`` > ``glue:Master step`` > these > dsim's default.
"""
from __future__ import annotations

from lxml import etree

from dsim.master.reading.ssp_values import NS

#: (annotation type, element local name, attribute, what messages call it)
TOOL_STEPS = (
    ("org.openmodelica", "FixedStepMaster", "stepSize", "OMSimulator"),
    ("com.opensimulationplatform", "FixedStepAlgorithm", "baseStepSize",
     "Open Simulation Platform"),
    # libcosim's predecessor (cse-core) read this one, on the root system
    ("org.open-simulation-platform", "FixedStepMaster", "stepSize",
     "Open Simulation Platform"),
)


def _annotations(root):
    """The ssc:Annotation elements of the DefaultExperiment and of the root system."""
    for owner in ("ssd:DefaultExperiment", "ssd:System"):
        element = root.find(owner, NS)
        if element is not None:
            yield from element.findall("ssd:Annotations/ssc:Annotation", NS)


def tool_step(root, shown: str) -> tuple[str, str, str] | None:
    """The macro step another tool's annotation sets, as the file writes it: (text,
    the element and attribute for a message, where it came from), or None.  The
    planning layer converts and checks it
    (:func:`dsim.master.planning.load.with_master_settings`)."""
    for annotation in _annotations(root):
        for kind, name, attribute, tool in TOOL_STEPS:
            if annotation.get("type") != kind:
                continue
            for element in annotation.iter():
                if not isinstance(element.tag, str) or etree.QName(element).localname != name:
                    continue
                text = element.get(attribute)
                if text is None:
                    continue
                where = (f"{shown} (SystemStructure.ssd line {element.sourceline}): {tool} "
                         f"annotation {name}: {attribute}")
                return text, where, f"{tool} annotation ({name} {attribute})"
    return None
