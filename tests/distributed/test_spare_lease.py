"""A cluster's spare worker waits for a run (master/running/backends/ray/lease.py):
taken once, ended when its wait runs out untaken, and once taken when the driver that
took it is gone; given back, it waits again.  With a job table and an end of the
test's making, so that the times are the test's."""
import threading
import time

from dsim.master.running.backends.ray import lease as ray_lease


class Ends:
    """What a lease ended with (an exit code), in place of ending the process."""

    def __init__(self):
        self.codes, self.done = [], threading.Event()

    def __call__(self, code):
        self.codes.append(code)
        self.done.set()


def test_a_spare_is_taken_once_and_ends_untaken_after_its_wait():
    ends = Ends()
    lease = ray_lease.Lease(0.3, alive=lambda job: True, end=ends)
    assert lease.take("01000000") and not lease.take("02000000")
    time.sleep(0.5)
    assert ends.codes == []  # taken: the wait does not end it
    assert not lease.give_back("02000000") and lease.give_back("01000000")
    assert ends.done.wait(2.0) and ends.codes == [0]  # waited again, untaken: ended
    assert not lease.take("02000000")  # too late


def test_a_taken_spare_ends_when_its_driver_job_has_ended(monkeypatch):
    monkeypatch.setattr(ray_lease, "OWNER_EVERY", 0.05)
    jobs = {"01000000": True}
    ends = Ends()
    lease = ray_lease.Lease(60, alive=lambda job: jobs[job], end=ends)
    assert lease.take("01000000")
    time.sleep(0.3)
    assert ends.codes == []
    jobs["01000000"] = False
    assert ends.done.wait(2.0) and ends.codes == [1]


def test_a_spare_is_not_taken_where_nothing_could_end_it():
    """No job table to read (or a job already ended): an unwatched worker could outlive
    its run, so it stays a spare."""
    def unreadable(job):
        raise RuntimeError("no job table")

    ends = Ends()
    assert not ray_lease.Lease(60, alive=unreadable, end=ends).take("01000000")
    assert not ray_lease.Lease(60, alive=lambda job: False, end=ends).take("01000000")
    assert ends.codes == []
