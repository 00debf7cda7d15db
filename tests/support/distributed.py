"""What the Ray tests share: a free port for a cluster's head, and the hint an answer
adds about token authentication."""


def free_port() -> int:
    """A TCP port free on this machine now (it may be taken again later)."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


#: what the answer for an address where no cluster answers adds in a process without
#: RAY_AUTH_MODE=token (ray_cluster._unreachable)
AUTHENTICATION = (" (a cluster with token authentication, the default of `ray start` since "
                  "Ray 2.52, also needs RAY_AUTH_MODE=token and its token here: "
                  "docs/distributed.md, \"Authentication\")")
