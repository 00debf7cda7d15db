"""The base of the observers that write one file as the run ends (:class:`FileWriter`)."""
from __future__ import annotations

import threading
from pathlib import Path

from dsim.master.recording.observers.base import RunInfo, Observer
from dsim.master.recording.output_files import OutputFile


class FileWriter(Observer):
    """A file written whole when the run ends, also when it failed or was
    interrupted (``content`` makes it; None: nothing to write); its temporary file
    is made and locked when the run starts (see :mod:`dsim.master.recording.output_files`), so that
    a run that cannot write it, or that another run is writing, is refused before
    anything runs; a failure to write it is a warning, never a replacement for how
    the run ended."""

    #: what the file is, for ``files`` and messages ("statistics", "plot", "mat")
    kind = ""

    def __init__(self, path):
        self.path = Path(path)
        self.output: OutputFile | None = None
        self.files = {}
        #: held while the file is written (a second signal waits for it, see abandoned)
        self._writing = threading.Lock()

    def started(self, info: RunInfo) -> None:
        self.output = OutputFile(self.path, info.inputs)
        self.output.open()

    def content(self, result) -> bytes | None:
        """The file's bytes for this result."""
        raise NotImplementedError

    def finished(self, result) -> None:
        with self._writing:
            if self.output is None or not self.output.is_open:
                return
            try:
                data = self.content(result)
                if data is None:
                    self.output.discard()
                    return
                self.output.append(data)
                self.output.commit()
            except Exception as error:  # a full disk must not hide how the run ended
                self.output.discard()
                result.warnings.append(f"{self.kind} not written to {self.path}: {error}")
                return
            self.files[self.kind] = self.path

    def aborted(self) -> None:
        if self.output:
            self.output.discard()
