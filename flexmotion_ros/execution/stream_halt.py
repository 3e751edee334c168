"""What the command stream reports: one step (:class:`StreamStep`) and how it ended (:class:`StreamHalt`).

Whatever ends a :class:`~.command_stream.CommandStream` -- ``stop``
(shutdown, deactivation) or a fault in the stream thread -- the last command
sent is the hold; :class:`StreamHalt` says what happened and what the
actuator got last.  A segment offered to a halted stream raises
:class:`StreamStopped`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from .timeline import HOLD, command_text


@dataclass(frozen=True, kw_only=True)
class StreamStep:
    """What one step of the stream did.

    Attributes
    ----------
    sample : int
        Global sample index (samples).
    deadline : float
        When it was due (clock s).
    time : float
        When it was handled, after the sleep (clock s).
    value : float or None
        The command published (N); None if nothing was sent (idle, silent).
    """

    sample: int
    deadline: float
    time: float
    value: float | None


class StreamStopped(RuntimeError):
    """A segment offered to a stream that has halted (shutdown, deactivation, a fault): nothing is installed.

    A request still being planned when the node shuts down ends so: the caller
    answers it as not planned, not as an internal failure.
    """


class HaltCause(Enum):
    """Why the stream ended (the values are the strings the log shows)."""

    STOPPED = "stopped"  # stop() was called: shutdown, deactivation
    FAULT = "fault"  # the publisher or a callback raised in the stream thread


@dataclass(frozen=True, kw_only=True)
class StreamHalt:
    """How the stream ended: the hold that closed it.

    Attributes
    ----------
    cause : HaltCause
        ``stopped`` (:meth:`CommandStream.stop`) or ``fault``.
    why : str
        The caller's reason (``"shutdown"``, ``"deactivated"``) or the fault (exception and message).
    held : bool
        The last command sent is the hold (:data:`~.timeline.HOLD`); False only if
        publishing the hold failed too (see ``hold_error``).
    hold_sent : bool
        A hold sample was sent to end it (False: the last command sent was already the hold, or none was sent).
    interrupted : bool
        A move was in progress: its remaining commands were dropped.
    sample : int
        Global index (samples) of the next sample not sent.
    last_value : float or None
        The last command sent before the halt (N); None if none was ever sent.
    hold_error : str
        Why publishing the hold failed ("" if it did not).
    """

    cause: HaltCause
    why: str
    held: bool
    hold_sent: bool
    interrupted: bool
    sample: int
    last_value: float | None
    hold_error: str = ""

    def describe(self) -> str:
        """One line for the log: what ended the stream and what the actuator got last."""
        if self.hold_sent:
            what = f"hold ({HOLD:g}) sent at sample {self.sample - 1}"
        elif self.held:
            what = f"the last command sent was already the hold ({HOLD:g})"
        elif self.last_value is None:
            what = "no command was ever sent"
        else:
            what = (
                f"the hold could NOT be sent ({self.hold_error}); the last command sent was "
                f"{command_text(self.last_value)}"
            )
        cut = "; the move in progress was cut off" if self.interrupted else ""
        return f"command stream {self.cause.value} ({self.why}): {what}{cut}"


__all__ = ["HaltCause", "StreamHalt", "StreamStep", "StreamStopped"]
