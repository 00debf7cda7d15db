"""Recording a run: observers, the files they write (safely), results and statistics."""
