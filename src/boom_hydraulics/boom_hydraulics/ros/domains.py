"""boom-demo's DDS domain: one of its own unless the user names one, and never one that
another boom-demo on this machine runs in.

Two demos in one domain hear each other: each node takes both demos' valve commands, and
each demo prints the other node's states. Without ``ROS_DOMAIN_ID`` boom-demo takes a free
domain of :data:`DEMO_DOMAINS` for itself and its node, seen from this machine only
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, unless that is set). With ``ROS_DOMAIN_ID``
it runs there (to be watched from the user's tools), and refuses to start while another
boom-demo runs in it. Which demo holds a domain is an exclusive lock on a file per domain
in the temporary folder, which the system releases when its holder ends, however it ends.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from collections.abc import MutableMapping
from pathlib import Path
from typing import IO

from ..errors import ConfigError

#: The domains boom-demo takes for itself: 215-232, the upper range the ROS 2 docs give as
#: safe on Linux, clear of a user's usual 0-101 and of the test suite's 100-199.
DEMO_DOMAINS = range(215, 233)
#: The largest domain id ROS 2 takes.
MAX_DOMAIN = 232


def _hold(domain: int) -> IO | None:
    """The lock of ``domain``, held open; None if another process holds it."""
    lock = open(Path(tempfile.gettempdir()) / f"boom_hydraulics-demo-domain-{domain}.lock", "a")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        return None
    return lock


def claim(environ: MutableMapping[str, str]) -> tuple[int, bool, IO]:
    """The domain boom-demo runs in, set in ``environ`` (with the discovery range, for a domain
    of its own); whether it is its own; and the lock that holds it (keep it open while the
    demo and its node run)."""
    given = environ.get("ROS_DOMAIN_ID", "").strip()
    if given:
        try:
            domain = int(given)
        except ValueError:
            domain = -1
        if not 0 <= domain <= MAX_DOMAIN:
            raise ConfigError(f"ROS_DOMAIN_ID={given!r}: expected a whole number in [0, {MAX_DOMAIN}]")
        lock = _hold(domain)
        if lock is None:
            raise ConfigError(
                f"another boom-demo runs in ROS_DOMAIN_ID {domain} on this machine: the two nodes would take each "
                "other's commands; wait for it to end, or unset ROS_DOMAIN_ID (boom-demo then takes a domain of "
                "its own)"
            )
        return domain, False, lock
    start = os.getpid() % len(DEMO_DOMAINS)
    for k in range(len(DEMO_DOMAINS)):
        domain = DEMO_DOMAINS[(start + k) % len(DEMO_DOMAINS)]
        lock = _hold(domain)
        if lock is not None:
            environ["ROS_DOMAIN_ID"] = str(domain)
            environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            return domain, True, lock
    raise ConfigError(
        f"every ROS domain boom-demo takes for itself ({DEMO_DOMAINS.start}-{DEMO_DOMAINS.stop - 1}) is held by "
        "another boom-demo on this machine; set ROS_DOMAIN_ID to a free one"
    )
