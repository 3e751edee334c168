"""Learning from moves (a part of :class:`~.planner_node.PlannerNode`, through :class:`~.planner_identify.IdentifyHandling`).

``identification.learn_from_moves: true``: a record opened at a move from rest
(:meth:`~.planner_identify.IdentifyHandling._identification_segment_started`)
goes on over later moves; at the end of a timeline the stream keeps sending
the hold for ``identification.ringdown_s`` (a lockstep plant rings down in
the record), then a background thread fits the record
(:func:`~flexmotion_ros.execution.learning.fit_record`) and, when confident,
adopts the parameters the data contradict through the node's own parameter
services (:meth:`LearningHandling._adopt`, also ``~/identify``'s adoption).
"""

from __future__ import annotations

import time

from rclpy.parameter import Parameter

from ..core.errors import FlexmotionError
from ..execution.learning import fit_record, model_update, summary
from ..execution.records import paired_record

#: The learner checks for an idle machine this often (s).
LEARN_POLL_S = 0.05


class LearningHandling:
    """Learning from moves and the adoption of a fit (a mixin of :class:`~.planner_node.PlannerNode`)."""

    # --------------------------------------------------------- stream hook
    def _identification_move_ended(self) -> None:
        """The stream thread, after the hold that ends a timeline: the ringdown starts.

        While a learning record is open the stream keeps sending the hold for
        ``identification.ringdown_s`` (whatever ``publish_hold_when_idle``
        says), so that a lockstep plant, which advances only with commands,
        rings down in the record; then it goes silent again.
        """
        self._last_end = (self._sent_log.count - 1, time.monotonic())
        if self._record_first is not None and self._ident.learn_from_moves and not self.stream.hold_when_idle:
            self._ringdown_holds = True
            self.stream.hold_when_idle = True

    # ------------------------------------------------------------ adoption
    def _adopt(self, update, source: str) -> str:
        """Set the changed model.* parameters through the node's own validated path; the outcome in words."""
        if not update.confident:
            return f"not adopted: not confident ({update.reason})"
        params = [Parameter(k, value=v) for k, v in update.parameters.items()]
        result = self.set_parameters_atomically(params) if params else None
        if result is not None and not result.successful:
            return f"not adopted: the parameters were refused ({result.reason})"
        intervals = (
            "; auto_robust.omega_min/max set to the 95 % intervals"
            if "auto_robust.omega_min" in update.parameters
            else ""
        )
        if not update.changes:
            return "nothing adopted: the data agree with the model" + intervals
        self._ident_status["learned_updates"] = int(self._ident_status.get("learned_updates", 0)) + 1
        return "adopted for the next goal: " + ", ".join(update.changes) + intervals

    # ------------------------------------------------------------- learning
    def _learn_loop(self) -> None:
        while not self._learn_stop.wait(LEARN_POLL_S):
            try:
                self._learn_step()
            except Exception as exc:  # noqa: BLE001 -- learning never takes the node down
                self.get_logger().error(f"learning from moves: {type(exc).__name__}: {exc}")
                self._record_first = None

    def _end_ringdown_holds(self) -> None:
        """The ringdown is recorded: the stream holds while idle only if ``publish_hold_when_idle`` says so."""
        if self._ringdown_holds:
            self._ringdown_holds = False
            self.stream.hold_when_idle = bool(self.get_parameter("publish_hold_when_idle").value)

    def _learn_step(self) -> None:
        first, ended = self._record_first, self._last_end
        if not self._ident.learn_from_moves:
            self._end_ringdown_holds()
        if first is None or ended is None or not self._ident.learn_from_moves:
            return
        end_index, end_time = ended
        if end_index <= self._fitted_upto or end_index < first or not self.stream.idle:
            return
        if time.monotonic() - end_time < self._ident.ringdown_s:
            return
        self._end_ringdown_holds()
        cfg, settings = self._config, self._ident
        # the commands whose readings are in: a lockstep plant may lag the stream, whose holds go on while idle
        newest = self._readings.count - 1
        if newest < 0:
            return
        stamp = int(self._readings.rows(newest, newest)[0][0])
        last = self._sent_log.first_at_or_after(stamp + 1) - 1
        if last < end_index:
            return  # the move's own readings are not all in yet
        if (last - first) / cfg.rate_hz > settings.max_record_s:
            self._record_first = None
            self.learned.append("record dropped: longer than identification.max_record_s")
            self.get_logger().info(
                f"learning from moves: the record exceeds identification.max_record_s = {settings.max_record_s:g} s; "
                "a new one starts at the next move from rest"
            )
            return
        self._fitted_upto = end_index
        try:
            record = paired_record(self._sent_log, self._readings, first, last, None, 1.0 / cfg.rate_hz)
            result = fit_record(record, self._mmap, cfg.model, settings.modes_for(cfg.model), cfg.u_max)
        except FlexmotionError as exc:
            note = f"not learned from {self._record_moves} move(s): {exc}"
            self.learned.append(note)
            self._ident_status["identification"] = note
            self.get_logger().info(f"learning from moves: {note}")
            return
        update = model_update(cfg.model, result, settings)
        outcome = self._adopt(update, "learning")
        note = f"from {self._record_moves} move(s), {record.samples} samples: {summary(result)}; {outcome}"
        self.learned.append(note)
        self._ident_status["identification"] = f"learned {note}"
        self.get_logger().info(f"learning from moves: {note}")
        self.publish_diagnostics()


__all__ = ["LEARN_POLL_S", "LearningHandling"]
