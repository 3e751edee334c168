"""Identification on the machine: ``~/identify`` and learning from moves (a part of :class:`~.planner_node.PlannerNode`).

``~/identify`` (std_srvs/Trigger), from rest: designs a bounded excitation
of ``identification.band`` (:func:`~flexmotion_ros.core.identification.design_excitation`:
``|u| <= u_max``, inside the position limits, back at rest where it started
for the believed model, a quiet tail for the ringdown), plays it through the
normal command stream (so the hold ends it, and a stop, a goal, a
deactivation or a shutdown cut it off with the hold like any move), records
the machine's ``measurements`` and the commands actually sent, paired by
sample (:func:`~flexmotion_ros.execution.learning.paired_record`), fits the
modal model (:func:`~flexmotion_ros.core.identification.identify`) and
answers with the numbers: each frequency and damping ratio with its 95 %
interval, ``b0``, the noise and the fit.  With ``identification.adopt: true``
every parameter the data contradict (its current value outside the 95 %
interval) takes the estimate, through the node's own parameter services
(``set_parameters_atomically``: validated like any ``ros2 param set``, visible
to ``ros2 param get``); the next goal plans with it.  Refused with the reason:
not active, a move in progress, no fresh measured state or not at rest, no
publisher on ``measurements``, readings missing or stale, the fit refused
(the core's one-line reason), the excitation cut off.

``identification.learn_from_moves: true``: a record starts at a move from
rest (measured), takes every command sent and every reading from then on
(later moves, their ringdowns) up to ``identification.max_record_s``; once the
machine has been idle for ``identification.ringdown_s`` the record is fitted
and, when confident (intervals narrower than ``identification.max_omega_interval``
/ ``identification.max_zeta_interval``), adopted as above.  The log and
``/diagnostics`` say what was learned.  This module keeps the setup, the
stream's hooks and the service; the learning thread and the adoption are
:mod:`.planner_learning`.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.task import Future
from std_srvs.srv import Trigger

from ..core.errors import FlexmotionError
from ..core.identification.excitation import design_excitation
from ..core.model.measurement import MeasurementMap, measurement_map
from ..core.multi_input.dispatch import n_inputs
from ..core.simulation.exact import modal_amplitudes, simulate_samples
from ..execution.learning import (
    REST_TOL,
    ExcitationRecord,
    IdentificationSettings,
    default_band,
    fit_record,
    identification_settings,
    model_update,
    summary,
)
from ..execution.realtime import normal_scheduling
from ..execution.records import RECORD_CAPACITY_S, SignalLog, paired_record
from ..execution.timeline import Segment
from .measurement_listener import MeasurementListener
from .multi_axis import is_multi
from .planner_learning import LearningHandling
from .planner_moves import MoveRecord

#: After the excitation's last command, readings may still be in flight this long (s) beyond ``state.timeout_s``.
READINGS_GRACE_S = 2.0
#: ``~/identify`` waits this long (s) for its new ``measurements`` subscription to match a publisher.
MATCH_WAIT_S = 2.0


class _Refused(Exception):
    """An identification refused: the reason is the message."""


class IdentifyHandling(LearningHandling):
    """``~/identify`` and learning from moves (a mixin of :class:`~.planner_node.PlannerNode`; the learning itself: :class:`~.planner_learning.LearningHandling`)."""

    # ------------------------------------------------------------------ setup
    def _setup_identification(self, v: dict[str, Any]) -> None:
        """Logs, the ``measurements`` listener, ``~/identify`` and the learner thread (configure)."""
        self._ident: IdentificationSettings = identification_settings(v)
        model = self._config.model
        rigid_names = tuple(model.rigid_bodies) if is_multi(self._config) else ("rigid_body",)
        self._mmap: MeasurementMap = measurement_map(v, model.n_modes, rigid_names)
        capacity = int(math.ceil(RECORD_CAPACITY_S * self._config.rate_hz)) + 1
        self._sent_width = n_inputs(self._config)  # one column per input (identification fits one input)
        self._sent_log = SignalLog(capacity, self._sent_width)
        self._readings = SignalLog(capacity, self._mmap.channels)
        self._measurements: MeasurementListener | None = None
        self._listener_lock = threading.Lock()
        self._identifying = False
        self._ident_lock = threading.Lock()
        self._ident_status: dict[str, Any] = {"identification": "none yet", "learned_updates": 0}
        #: The learning record: index of its first command in the sent log (None: no record).
        self._record_first: int | None = None
        self._ringdown_holds = False  # the stream holds for a ringdown, not for publish_hold_when_idle
        self._record_moves = 0
        self._last_end: tuple[int, float] | None = None  # (sent index of the last hold, monotonic time)
        self._fitted_upto = -1  # the last sent index a learning fit covered
        self.learned: list[str] = []  # what each learning fit did (for tests and the log)
        self._learn_stop = threading.Event()
        self._learner = threading.Thread(target=self._learn_loop, name="flexmotion-learn", daemon=True)
        self._learner.start()
        self._listen_as_needed()
        self.create_service(Trigger, "~/identify", self._on_identify, callback_group=ReentrantCallbackGroup())

    def _listen_as_needed(self) -> MeasurementListener | None:
        """Subscribe to ``measurements`` only while learning or identifying (a 1 kHz callback costs the stream)."""
        with self._listener_lock:
            wanted = self._ident.learn_from_moves or self._identifying
            if wanted and self._measurements is None:
                self._measurements = MeasurementListener(self, self._mmap.names, self._readings)
            elif not wanted and self._measurements is not None:
                listener, self._measurements = self._measurements, None
                listener.close()
            return self._measurements

    def _close_identification(self) -> None:
        """Stop the learner and the listener (cleanup, destroy)."""
        stop = getattr(self, "_learn_stop", None)
        if stop is not None:
            stop.set()
            self._learner.join(timeout=5.0)
        lock = getattr(self, "_listener_lock", None)
        if lock is not None:
            with lock:
                listener, self._measurements = self._measurements, None
            if listener is not None:
                listener.close()

    def _apply_identification(self, v: dict[str, Any]) -> None:
        self._ident = identification_settings(v)
        self._listen_as_needed()

    def _identification_values(self) -> dict[str, Any]:
        """Values on /diagnostics."""
        return dict(self._ident_status)

    # --------------------------------------------------------- stream hooks
    def _record_sent(self, value: float, t_ns: int | None = None) -> None:
        """The stream thread, just before publishing a command: log its system time (``t_ns``: the stream process's) and value."""
        row = (value,) if self._sent_width == 1 else np.broadcast_to(np.asarray(value, float), (self._sent_width,))
        self._sent_log.append(time.time_ns() if t_ns is None else t_ns, row)

    def _identification_segment_started(self, seg: Segment) -> None:
        """The stream thread, after a segment's first command: where it is in the sent log."""
        index = self._sent_log.count - 1
        rec = seg.info
        if isinstance(rec, ExcitationRecord):
            rec.first = index
            rec.started.set()
            return
        if not (isinstance(rec, MoveRecord) and self._ident.learn_from_moves) or is_multi(self._config):
            return
        if self._record_first is not None:
            self._record_moves += 1  # a later move: the record goes on
            return
        x0 = seg.states[0]
        still = abs(x0[1]) <= REST_TOL and np.all(modal_amplitudes(self._config.model, x0) <= REST_TOL)
        if rec.from_idle and still:
            self._record_first, self._record_moves, self._fitted_upto = index, 1, -1

    # -------------------------------------------------------------- service
    async def _on_identify(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        done: Future = Future()

        def work() -> None:
            normal_scheduling()  # created by an executor callback (SCHED_FIFO under stream_priority): it computes
            try:
                out = self.identify_now()
            except Exception as exc:  # noqa: BLE001 -- identify_now refuses instead of raising; never unanswered
                out = (False, f"{type(exc).__name__}: {exc}")
            done.set_result(out)
            self._wake_executor()

        threading.Thread(target=work, name="flexmotion-identify", daemon=True).start()
        response.success, response.message = await done
        return response

    def identify_now(self) -> tuple[bool, str]:
        """Run the excitation, record, fit, report (and adopt): ``(success, message)``; never raises for bad input."""
        if not self._ident_lock.acquire(blocking=False):
            return self._ident_refuse("an identification is already running")
        try:
            self._identifying = True
            return self._identify()
        except _Refused as exc:
            return self._ident_refuse(str(exc))
        except FlexmotionError as exc:
            return self._ident_refuse(str(exc))
        finally:
            self._identifying = False
            self._listen_as_needed()
            self._ident_lock.release()

    def _ident_refuse(self, reason: str) -> tuple[bool, str]:
        self.get_logger().error(f"~/identify: refused: {reason}")
        self._ident_status["identification"] = f"refused: {reason}"
        self.publish_diagnostics()
        return False, reason

    def _check_at_rest(self) -> np.ndarray:
        """The measured state, at rest, or :class:`_Refused` with the reason."""
        if self._lifecycle != "active":
            raise _Refused(f"the planner is {self._lifecycle} (lifecycle): activate it to identify")
        if not self.stream.idle:
            raise _Refused("not at rest: a move is in progress; identify from rest")
        if self.commands_publisher.get_subscription_count() == 0:
            raise _Refused("no subscriber is matched on 'commands': nothing would move")
        if self._listener is None:
            raise _Refused("state.source is 'assumed': identification needs the measured state to start from rest")
        x0 = self._listener.store.fresh(self._state_joints, self._state.timeout_s, self._listener.topic)
        amp = float(np.max(modal_amplitudes(self._config.model, x0), initial=0.0))
        if abs(x0[1]) > REST_TOL or amp > REST_TOL:
            raise _Refused(
                f"not at rest: velocity {x0[1]:.3g}, largest modal amplitude {amp:.3g} (allowed {REST_TOL:g}); "
                "wait for the machine to settle (or ~/stop it)"
            )
        listener = self._listen_as_needed()
        end = time.monotonic() + MATCH_WAIT_S
        while listener.publisher_count() == 0:
            if time.monotonic() > end:
                raise _Refused(
                    f"measurements: no publisher on {listener.topic!r} matched within {MATCH_WAIT_S:g} s: nothing to record"
                )
            time.sleep(0.01)
        return x0

    def _identify(self) -> tuple[bool, str]:
        cfg, settings, mmap = self._config, self._ident, self._mmap
        if is_multi(cfg):
            raise _Refused(
                f"identification fits one input; this model has {n_inputs(cfg)} (model.inputs): identify each "
                "drive with a single-input parameter file"
            )
        modes = settings.modes_for(cfg.model)
        if modes > 0 and not np.any(mmap.sees_modes()):
            raise _Refused(
                f"measurement.map: no measured channel ({', '.join(mmap.names)}) reads a mode; give "
                "measurement.names/map (flexmotion model ... writes them)"
            )
        x0 = self._check_at_rest()
        band = settings.band or default_band(cfg.model, cfg.rate_hz)
        exc = design_excitation(
            cfg.model,
            cfg.u_max,
            cfg.rate_hz,
            band,
            duration=settings.duration_s,
            position_limits=(cfg.position_min, cfg.position_max),
            start=float(x0[0]),
        )
        K = exc.commands.size
        if K + 1 > self._sent_log.capacity:
            raise _Refused(
                f"identification.duration_s: {exc.duration:.4g} s is longer than the {RECORD_CAPACITY_S:g} s kept"
            )
        states = simulate_samples(cfg.model, cfg.model.rest_state(float(x0[0])), exc.commands, 1.0 / cfg.rate_hz)
        rec = ExcitationRecord(band=tuple(band))
        seg = Segment(np.asarray(exc.commands, float), np.asarray(states, float), info=rec)
        with self._install_lock:
            if not self.stream.idle:
                raise _Refused("not at rest: a move started meanwhile")
            self.stream.start_now(seg)
            version = self.stream.version
            self.installed.append(seg)
            self._position = float(x0[0])
            self._predicted_end = np.array(states[-1], float)
        self._ident_status["identification"] = f"exciting {band[0]:.4g}..{band[1]:.4g} rad/s for {exc.duration:.4g} s"
        self.get_logger().info(
            f"~/identify: exciting {band[0]:.4g}..{band[1]:.4g} rad/s for {exc.duration:.4g} s ({K} samples, peak "
            f"{exc.peak:.4g}, set by {exc.bound}) from {x0[0]:.6g}, at sample {seg.start}"
        )
        self.publish_diagnostics()
        self._wait_played(seg, version, exc.duration)
        last = rec.first + K  # the explicit hold that ends it
        self._wait_readings(last)
        record = paired_record(self._sent_log, self._readings, rec.first, last, None, 1.0 / cfg.rate_hz)
        result = fit_record(record, mmap, cfg.model, modes, cfg.u_max)
        update = model_update(cfg.model, result, settings)
        text = summary(result) + ("" if record.exact else " (readings on the plant's clock: approximate pairing)")
        adopted = ""
        if settings.adopt:
            adopted = self._adopt(update, "~/identify")
        else:
            adopted = "not adopted (identification.adopt: false)" + (
                f"; the data contradict: {', '.join(update.changes)}" if update.changes else ""
            )
        message = f"identified: {text}; {adopted}"
        self._ident_status["identification"] = message
        self.get_logger().info(f"~/identify: {message}")
        self.publish_diagnostics()
        return True, message

    def _wait_played(self, seg: Segment, version: int, duration: float) -> None:
        """Until the excitation has played to its hold; :class:`_Refused` if it was cut off."""
        if not seg.info.started.wait(5.0):
            raise _Refused("the excitation did not start within 5 s")
        end = time.monotonic() + duration + 10.0
        while True:
            halted = self.stream.halted
            if halted is not None:
                raise _Refused(f"cut off: {halted.describe()}; nothing identified")
            if self.stream.version != version:
                raise _Refused("cut off by a stop or a goal during the excitation (with the hold); nothing identified")
            if self.stream.idle:
                return
            if time.monotonic() > end:
                raise _Refused("the excitation did not end in time")
            time.sleep(0.01)

    def _wait_readings(self, last: int) -> None:
        """Until a reading stamped at or after command ``last`` was sent arrives (a lagging plant), or time out."""
        end = time.monotonic() + self._state.timeout_s + READINGS_GRACE_S
        # the stream goes idle as it takes the closing hold, just before it publishes (and logs) it
        while self._sent_log.count <= last:
            if time.monotonic() > end:
                raise _Refused("the excitation's closing hold was not sent")
            time.sleep(0.001)
        t_last = int(self._sent_log.rows(last, last)[0][0])
        while self._readings.first_at_or_after(t_last) >= self._readings.count:
            if time.monotonic() > end:
                return  # paired_record says what is missing
            time.sleep(0.01)


__all__ = ["IdentifyHandling"]
