"""The loading program: pressure stages, each run until equilibrium, with frames and checkpoints.

A stage ends after the first step, once its load is fully applied, at which φ differs by less
than ``phi_tolerance`` (relative) from φ ``check_every`` steps before, the inertial number is
below ``inertial_tolerance`` (:func:`compute.bodies.walls.inertial_number`), and, when
``force_tolerance`` is set, the contact force on every wall balances the applied one within that
relative tolerance (slow is not static: a damped wall can creep while its force is still out of
balance). Its last state is written as an equilibrated frame. The test runs after every step
over a sliding window of check_every steps. Why: tested only every check_every steps, against
the φ of the previous test, a stage waited up to check_every - 1 steps past the first one
that passes, and always ran at least 2 check_every steps; a shorter check_every allows a faster
creep (φ may drift by phi_tolerance per window). The sliding window ends stages earlier at the
same distance from a ten times tighter test (benchmarks/results/stage_window_144.md).

A run asked to stop (SIGTERM, or a file OUT/STOP, read after every step) stops at the end of the
step it is computing: it writes a checkpoint, then dies by SIGTERM, as a killed run (nothing
marked, studies.dispatch resumes it), having lost nothing. A second SIGTERM kills it at once,
also inside a compiled kernel (:mod:`compute.stop_watch`), losing the steps since its last
checkpoint.
Why: a step of a large soft mixture at high pressure takes minutes, and a machine given back at
a fixed time should lose none of them; the file is how a study's dispatcher, which does not know
the processes its workers started, asks its runs to stop.
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import sys
import threading
import time
import tomllib
import zipfile
from pathlib import Path

import numpy as np

from compute import files, output, output_folder, schema, stall, summary, wall_crossing
from compute.stop_watch import second_sigterm_kills
from compute.threads import ThreadsFile
from compute.errors import OutputFolderError, OutputWriteError, SimulationError
from compute.bodies.soft import mass_scale
from compute.model import Model
from compute.progress import Display, RunProgress
from compute.scene import read_scene
from compute.state import State
from compute.stepping import load_control
from compute.stepping.moreau_jean import Stepper
from compute.frames import wall_forces
from compute.bodies.walls import breathing_damping, inertial_number, stage_bulk_modulus, wall_lengths

STOP_FILE = "STOP"  # OUT/STOP asks the run to stop after its step (module docstring)

# φ above 1 with a soft boundary beyond the walls stops the run (compute.wall_crossing)
PHI_LIMIT = 1.0 + 1e-9


class Run:
    """A run of a scene into an output folder; ``execute`` does the whole loading program.

    The output folder's lock (:mod:`compute.output_folder`) is held from construction until
    ``execute`` returns; ``wait``: wait for another compute writing the folder instead of
    refusing; ``bodies_outside``: accept a bodies file outside the scene folder (read_scene).
    Progress (:mod:`compute.progress`) goes to ``display`` (default: stderr, a bar on a terminal,
    plain lines otherwise) and to OUT/progress.json."""

    def __init__(self, scene_dir: str | Path, out_dir: str | Path, resume: bool = False, log=None,
                 wait: bool = False, display: Display | None = None, checkpoint_minutes: float | None = None,
                 bodies_outside: bool = False):
        if checkpoint_minutes is not None and not checkpoint_minutes > 0.0:
            raise ValueError(f"checkpoint_minutes: expected a positive number of minutes, got {checkpoint_minutes!r}")
        self.scene = read_scene(scene_dir, bodies_outside)  # a bad scene stops before anything is written
        self.checkpoint_seconds = None if checkpoint_minutes is None else 60.0 * checkpoint_minutes
        self._last_checkpoint = time.monotonic()
        self._stop_asked: str | None = None  # what asked the run to stop
        self.out = Path(out_dir)
        self.log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
        self.model = build_model(self.scene)
        self.stepper = Stepper(self.model)
        self._threads = ThreadsFile(self.out, self.log)  # OUT/threads, read after every step
        self._display = display
        self._lock = output_folder.acquire(self.out, wait)  # held until execute() returns
        try:
            self.state = self._start(resume)
            self.history = output.History(self.out / "history.csv", self.state.step if resume else None)
            if self.history.missing:
                gaps = ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in self.history.missing)
                self.log(f"warning: {self.out / 'history.csv'} has no rows for steps {gaps} before the checkpoint "
                         f"at step {self.state.step} (a copy older than the checkpoint); going on from the checkpoint")
        except OutputWriteError as exc:
            self._best_effort(lambda: files.write_text(self.out / "FAILED", f"{exc}\n"))
            output_folder.release(self._lock)
            raise
        except BaseException:
            output_folder.release(self._lock)
            raise

    # --- set-up ------------------------------------------------------------------------
    def _start(self, resume: bool) -> State:
        for folder in (self.out / "frames", self.out / "checkpoint"):
            with files.guarded(folder):
                folder.mkdir(parents=True, exist_ok=True)
        output.remove_temporaries(self.out)
        ckpt = self.out / output.CHECKPOINT
        frames_csv = self.out / "frames.csv"
        if resume and files.is_file(ckpt, OutputFolderError):
            self._check_same_scene()
            state = _read_checkpoint(ckpt)
            if state.q.shape != (self.model.n_dofs,):
                raise OutputFolderError(ckpt, "q", f"the {self.model.n_dofs} dofs of the scene's model", state.q.shape)
            rows = [r for r in output.read_frame_rows(frames_csv) if (r["frame"] or "").isdigit()
                    and int(r["frame"]) < state.frame]
            if [int(r["frame"]) for r in rows] != list(range(state.frame)):
                raise OutputFolderError(frames_csv, "frame", f"the rows of frames 0..{state.frame - 1} written before "
                                        f"the checkpoint at step {state.step}", [r["frame"] for r in rows])
            for name in (*summary.MARKERS, "FAILED"):  # the run goes on: its last end no longer holds
                files.remove(self.out / name)
            for f, frame in output.frame_files(self.out).items():
                if frame >= state.frame:
                    files.remove(f)
            output.write_frame_rows(frames_csv, rows)
            output.write_pvd(self.out, rows)
            self.log(f"resuming from step {state.step}, stage {state.stage}, frame {state.frame}")
            return state
        if resume:
            self.log(f"no checkpoint in {self.out}: starting from the scene")
        for f in output.frame_files(self.out):
            files.remove(f)
        for name in ("frames.csv", output.CHECKPOINT, "FAILED", "summary.json", *summary.MARKERS):
            files.remove(self.out / name)
        files.write_atomic(self.out / "scene.toml", lambda tmp: shutil.copyfile(self.scene.path / "scene.toml", tmp))
        output.write_frame_rows(frames_csv, [])
        return self.model.initial_state()

    def _check_same_scene(self) -> None:
        """A run resumes only the scene it was started from (its copy OUT/scene.toml), both read
        in the current schema version (a run started under an older one resumes)."""
        started = self.out / "scene.toml"
        if not files.is_file(started, OutputFolderError):
            return
        try:
            before = tomllib.loads(files.read_text(started, OutputFolderError))
        except tomllib.TOMLDecodeError as exc:
            raise OutputFolderError(started, "<syntax>", "the copy of the scene's scene.toml", str(exc)) from None
        before = schema.migrate(started, before, OutputFolderError)
        if before != self.scene.raw:
            changed = sorted(_changed_keys(before, self.scene.raw))
            raise OutputFolderError(started, changed[0], f"the parameters of the scene being resumed "
                                    f"(changed: {', '.join(changed)}); run without --resume or into another folder",
                                    _dotted(self.scene.raw, changed[0]))

    # --- the program -------------------------------------------------------------------
    def execute(self) -> State:
        """Run all remaining stages; on a numerical failure (an overflow included) keep what was
        written, write FAILED with the diagnosis and raise SimulationError."""
        stages = 1 if self.scene.walls.control == "velocity" else len(self.scene.loading.pressures)
        self.progress = RunProgress(self.out, stages, self._display)
        on_main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGTERM, self._ask_stop) if on_main else None
        self._threads.poll()
        try:
            with second_sigterm_kills():
                return self._execute()
        finally:
            if on_main:
                signal.signal(signal.SIGTERM, previous)

    def _execute(self) -> State:
        """The program of :meth:`execute`, its signal handling set up."""
        finished = False
        try:
            stall_diagnosis = None
            if self.scene.walls.control == "velocity":
                self._velocity_stage()
            else:
                while self.state.stage < len(self.scene.loading.pressures) and stall_diagnosis is None:
                    stall_diagnosis = self._pressure_stage(self.scene.loading.pressures[self.state.stage])
            self.checkpoint()
            done = summary.run_summary(self.out, self.scene, self.state.step, stall_diagnosis)
            self.progress.finish(done["status"])
            finished = True
            summary.write(self.out, done)
            if done["status"] != "complete":
                self.log("WARNING: run INCOMPLETE: " + summary.incomplete_reasons(done).replace("\n", "; "))
        except (SimulationError, OverflowError, FloatingPointError) as exc:
            failure = exc if isinstance(exc, SimulationError) else SimulationError(
                f"step {self.state.step + 1}: numerical overflow ({type(exc).__name__}: {exc})")
            self._record_failure(failure)
            raise failure from None
        except OutputWriteError as exc:
            self._record_failure(exc)
            raise
        finally:
            if not finished:
                self._best_effort(lambda: self.progress.finish("failed"))
            self._best_effort(self.history.close)
            output_folder.release(self._lock)
        return self.state

    def _record_failure(self, failure: Exception) -> None:
        """Keep what was written and say why the run stopped: the history flushed, FAILED with
        the diagnosis. Each write is best effort: on a full disk the diagnosis still reaches the
        log, and --resume goes on from the last checkpoint once the cause is fixed."""
        self._best_effort(self.history.flush)
        self._best_effort(lambda: files.write_text(self.out / "FAILED", f"{failure}\n"))
        self.log(f"run stopped: {failure}")

    def _best_effort(self, write) -> None:
        """``write()``; a file it cannot write is logged, not raised (the run is already stopping)."""
        try:
            write()
        except OutputWriteError as exc:
            self.log(f"warning: {exc}")

    def _ask_stop(self, signum, frame) -> None:
        """SIGTERM handler: stop after this step (module docstring); the next SIGTERM kills."""
        self._stop_asked = "SIGTERM"
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

    def _pressure_stage(self, pressure: float) -> str | None:
        """Run the stage to its end; the diagnosis when it stalled (compute.stall: the run ends
        there), else None."""
        load = self.scene.loading
        previous = load.pressures[self.state.stage - 1] if self.state.stage else 0.0
        self.start_stage(pressure)
        if self.model.walls.stage_damping > 0.0 and self.state.stage_steps == 0:
            self.log(f"stage {self.state.stage}: wall damping at least {self.model.walls.stage_damping:.4g} "
                     f"(walls.damping_ratio)")
        while True:
            self.state, rep, applied, halvings = load_control.controlled_step(self.stepper, self.state, previous,
                                                                              pressure, self.log)
            st = self.state
            phi = self._record(rep, applied, halvings)
            st.phi_window = np.append(st.phi_window, phi)[-(load.check_every + 1):]
            ramped = st.load_fraction >= 1.0
            b = self.model.bounds(st.q)
            stall.record(st, rep.residual, phi, (b[1] - b[0]) * (b[3] - b[2]), ramped, self.scene)
            if stall.stalled(st, self.scene, rep.residual):
                self.write_frame(applied, equilibrated=False)
                diagnosis = stall.diagnosis(st, self.scene, pressure, rep.residual)
                self.log(diagnosis)
                self.progress.stage_done()
                return diagnosis
            if ramped and self._equilibrated(pressure):
                self.write_frame(pressure, equilibrated=True)
                self.log(f"stage {st.stage} (P = {pressure:.4g}) equilibrated at step {st.step}: "
                         f"phi = {self.model.phi(st.q):.6f}")
                break
            if st.stage_steps >= load.max_steps_per_stage:
                self.write_frame(applied, equilibrated=False)
                self.log(f"stage {st.stage} (P = {pressure:.4g}) NOT equilibrated after "
                         f"{st.stage_steps} steps; frame written with equilibrated = 0")
                break
            self._periodic_checkpoint()
        self.progress.stage_done()
        st.stage += 1
        st.stage_steps = 0
        st.phi_window = np.zeros(0)
        load_control.start_stage(st)
        stall.start_stage(st)
        self.checkpoint()
        return None

    def start_stage(self, pressure: float) -> None:
        """The model's settings for the pressure stage at ``pressure``, set before its first step
        and again when it is resumed: the soft bodies' inertia (compute.bodies.soft, mass scaling)
        and the walls' least damping (:meth:`_stage_damping`)."""
        solver = self.scene.solver
        for group in self.model.soft:
            group.scale_mass(mass_scale(solver.mass_scaling, pressure, solver.time_step,
                                        group.batch.material.density, self.model.diameter))
        self.model.walls.stage_damping = self._stage_damping(pressure)

    def _stage_damping(self, pressure: float) -> float:
        """The least wall damping of the stage at ``pressure`` (compute.bodies.walls.breathing_damping,
        stage_bulk_modulus) from the equilibrated frames written so far, the scene's initial box
        counting as one at P = 0 (its secant, the first stage's, also holds the packing's
        rearrangement, so it damps less, and it is not extrapolated); read from frames.csv so that
        a resumed stage gets the same value."""
        ratio = self.scene.walls.damping_ratio
        if ratio == 0.0:
            return 0.0
        rows = [r for r in output.read_frame_rows(self.out / "frames.csv") if int(r["equilibrated"])]
        bounds = np.array([self.model.walls.initial_bounds]
                          + [[float(r[k]) for k in ("xmin", "xmax", "ymin", "ymax")] for r in rows])
        pressures = np.array([0.0] + [float(r["pressure_applied"]) for r in rows])
        areas = (bounds[:, 1] - bounds[:, 0]) * (bounds[:, 3] - bounds[:, 2])
        return breathing_damping(ratio, stage_bulk_modulus(pressures, areas, pressure), self.model.particle_mass(),
                                 self.scene.walls.mass)

    def _velocity_stage(self) -> None:
        load = self.scene.loading
        n = int(round(load.duration / self.stepper.h))
        while self.state.stage_steps < n:
            self.state, rep = self.stepper.step(self.state, 0.0, load.velocity)
            self._record(rep, 0.0, 0)
            self._periodic_checkpoint()
        self.write_frame(0.0, equilibrated=False)
        self.progress.stage_done()
        self.state.stage = 1

    def _record(self, rep, pressure: float, halvings: int) -> float:
        """History row and frames after an accepted step; returns its φ. A step whose φ passes 1
        stops the run with a diagnosis before its row is written."""
        st = self.state
        self._threads.poll()  # a share of freed cores given by the dispatcher (compute.threads)
        self.last_contacts = rep.contacts
        st.stage_steps += 1
        b = self.model.bounds(st.q)
        phi = self.model.phi(st.q)
        if phi > PHI_LIMIT and wall_crossing.crossed(self.model, st.q):  # the step is not kept
            raise SimulationError(f"step {st.step} (stage {st.stage}, P = {pressure:.4g}): "
                                  + wall_crossing.diagnosis(self.model, st.q, phi))
        self.history.append(dict(
            time=st.time, step=st.step, stage=st.stage, pressure_applied=pressure,
            xmin=b[0], xmax=b[1], ymin=b[2], ymax=b[3], phi=phi, nlgs_sweeps=rep.sweeps,
            nlgs_residual=rep.residual, kinetic_energy=self.model.kinetic_energy(st.v),
            inertial_number=self._inertial(pressure), n_contacts=rep.n_contacts,
            max_penetration=rep.max_penetration, newton_iterations=rep.newton_iterations, cuts=rep.cuts,
            load_halvings=halvings, sub_steps=rep.sub_steps, hold_torque=rep.hold_torque))
        self.progress.step(st.stage, pressure, phi, st.step, st.stage_steps)
        out = self.scene.output
        if out.every_steps and st.step % out.every_steps == 0:
            self.write_frame(pressure, equilibrated=False)
        return phi

    def _periodic_checkpoint(self) -> None:
        """A checkpoint every ``checkpoint_every_steps`` steps, and, when ``checkpoint_minutes`` was
        given, whenever that much wall time has passed since the last one, and before a stop
        asked by SIGTERM; taken after the step's equilibrium check (a resumed run does not redo
        it). Why the wall-time one: a step of a large soft mixture at high pressure can take minutes, and a run stopped between two
        step-counted checkpoints would lose hours. It is not the default because a checkpoint is
        a restart point (Stepper.restart_point): the steps after it, and so the trajectory, then
        depend on when the checkpoints fell."""
        stop_file = self.out / STOP_FILE
        if not self._stop_asked and stop_file.is_file():
            self._stop_asked = "OUT/STOP"
        due = self.checkpoint_seconds is not None and time.monotonic() - self._last_checkpoint >= self.checkpoint_seconds
        if due or self._stop_asked or self.state.step % self.scene.output.checkpoint_every_steps == 0:
            self.checkpoint()
        if self._stop_asked:
            stop_file.unlink(missing_ok=True)  # honoured: a resume goes on
            self.log(f"stopped by {self._stop_asked} after step {self.state.step}, checkpoint written; resume to go on")
            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)  # no handler left: the process dies by SIGTERM

    def _inertial(self, pressure: float) -> float:
        m = self.model
        return inertial_number(m.bounds(self.state.q), m.wall_velocity(self.state.v), pressure, m.density, m.diameter)

    def _equilibrated(self, pressure: float) -> bool:
        """The stage-end test (module docstring) after the last step."""
        st, load = self.state, self.scene.loading
        window = st.phi_window
        if len(window) <= load.check_every:
            return False
        phi = window[-1]
        ok = abs(phi - window[0]) < load.phi_tolerance * phi and self._inertial(pressure) < load.inertial_tolerance
        if ok and load.force_tolerance > 0.0:
            applied = pressure * wall_lengths(self.model.bounds(st.q))
            contact = wall_forces(self.last_contacts, self.stepper.h)
            ok = bool(np.max(np.abs(contact - applied)) < load.force_tolerance * applied.min())
        return bool(ok)

    # --- files ---------------------------------------------------------------------------
    def write_frame(self, pressure: float, equilibrated: bool) -> None:
        """Write bodies, contacts and walls of the current state as frame ``state.frame``."""
        from compute.frames import write_frame_files

        st = self.state
        write_frame_files(self.out, st.frame, self.model, st, self.stepper.h, pressure)
        b = self.model.bounds(st.q)
        rows = output.read_frame_rows(self.out / "frames.csv")
        rows.append(dict(frame=st.frame, time=repr(st.time), step=st.step, stage=st.stage,
                         pressure_applied=repr(float(pressure)), equilibrated=int(equilibrated),
                         xmin=repr(float(b[0])), xmax=repr(float(b[1])), ymin=repr(float(b[2])), ymax=repr(float(b[3]))))
        output.write_frame_rows(self.out / "frames.csv", rows)
        output.write_pvd(self.out, rows)
        st.frame += 1

    def checkpoint(self) -> None:
        """Save the state atomically (after flushing the history up to this step); the run goes
        on from it exactly as a run resumed from it would (Stepper.restart_point)."""
        self.stepper.restart_point()
        self.history.flush()
        arrays = self.state.to_arrays()
        files.write_atomic(self.out / output.CHECKPOINT, lambda tmp: np.savez(tmp, **arrays))
        self._last_checkpoint = time.monotonic()


def _read_checkpoint(path: Path) -> State:
    """The state saved in the checkpoint ``path``; a file that is not one raises
    OutputFolderError naming it."""
    data = files.read_bytes(path, OutputFolderError)
    try:
        with np.load(io.BytesIO(data)) as arrays:
            return State.from_arrays(dict(arrays))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise OutputFolderError(path, "<file>", "a checkpoint written by compute (numpy .npz)",
                                f"{type(exc).__name__}: {exc}") from None


def _changed_keys(a, b, prefix: str = "") -> list[str]:
    """Dotted names of the values that differ between two parsed TOML documents."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [k for key in sorted(set(a) | set(b)) for k in _changed_keys(a.get(key), b.get(key), prefix + key + ".")]
    return [] if a == b else [prefix.rstrip(".")]


def _dotted(doc, name: str):
    for part in name.split("."):
        doc = doc.get(part) if isinstance(doc, dict) else None
    return doc


def build_model(scene) -> Model:
    """The model of a scene: its body groups and contact families."""
    return Model(scene)


def run(scene_dir: str | Path, out_dir: str | Path, resume: bool = False, log=None, wait: bool = False,
        checkpoint_minutes: float | None = None, bodies_outside: bool = False) -> State:
    """Run the scene in ``scene_dir`` and write frames, history and checkpoints in ``out_dir``."""
    return Run(scene_dir, out_dir, resume=resume, log=log, wait=wait, checkpoint_minutes=checkpoint_minutes,
               bodies_outside=bodies_outside).execute()
