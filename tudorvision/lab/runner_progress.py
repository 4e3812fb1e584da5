"""Progress of the experiment runner on stderr: a live ``rich`` bar on a terminal, plain lines otherwise."""
from __future__ import annotations

import time

__all__ = ["RunProgress", "format_eta"]

PLAIN_EVERY_S = 10.0     # plain mode: at most one line this often (and one at every failure and at the end)


def format_eta(seconds: float | None) -> str:
    """A duration as ``h:mm:ss`` (``?`` when unknown).

    Parameters
    ----------
    seconds : float or None
        Duration, s.

    Returns
    -------
    str
        The text.

    Examples
    --------
    >>> format_eta(3725.2), format_eta(None)
    ('1:02:05', '?')
    """
    if seconds is None or seconds != seconds or seconds == float("inf"):
        return "?"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


class RunProgress:
    """Done / running / failed counts and the ETA of a task run.

    Parameters
    ----------
    total : int
        Tasks in the run (including those found done).
    label : str
        Name shown first.
    enabled : bool or None
        ``None``: live bar when ``stream`` is a terminal, plain lines otherwise; ``False``: silent.
    stream : file
        Output (stderr).
    """

    def __init__(self, total: int, *, label: str, enabled: bool | None, stream):
        self.total, self.label, self.stream = total, label, stream
        self.enabled = enabled is not False
        self.live = self.enabled and (enabled is True or (hasattr(stream, "isatty") and stream.isatty()))
        self.n_skipped = self.n_done = self.n_failed = self.n_running = self.n_new = 0
        self.t0 = time.monotonic()
        self.last_line = 0.0
        self.bar = None

    # ----------------------------------------------------------------- events
    def skipped(self, n: int) -> None:
        """Tasks found done in the output folder.

        Parameters
        ----------
        n : int
            How many.
        """
        self.n_skipped = n
        self.n_done += n
        if n and self.enabled:
            self.stream.write(f"{self.label}: {n} of {self.total} already done in the output folder, skipped\n")
            self.stream.flush()

    def dashboard(self, address: str | None) -> None:
        """Print the Dask dashboard's address.

        Parameters
        ----------
        address : str or None
            The address (nothing printed for ``None``).
        """
        if address and self.enabled:
            try:
                import bokeh  # noqa: F401
                note = ""
            except ImportError:
                note = " (install bokeh to see it)"
            self.stream.write(f"{self.label}: Dask dashboard at {address}{note}\n")
            self.stream.flush()

    def start(self, *, running: int) -> None:
        """The tasks to run are submitted.

        Parameters
        ----------
        running : int
            Tasks running at first.
        """
        self.t0 = time.monotonic()
        self.n_running = running
        if self.live:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
            self.bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[counts]}"),
                                TimeElapsedColumn(), console=Console(file=self.stream), transient=False)
            self.bar_id = self.bar.add_task(self.label, total=self.total, completed=self.n_done,
                                            counts=self._counts())
            self.bar.start()

    def running(self, n: int) -> None:
        """Tasks running now.

        Parameters
        ----------
        n : int
            Count.
        """
        self.n_running = n
        self._show()

    def retry(self, key: str, error: str) -> None:
        """A task raised and is tried again.

        Parameters
        ----------
        key : str
            Its key.
        error : str
            The error's first line.
        """
        self._say(f"{self.label}: {key} raised {error}; trying it again")

    def finished(self, *, ok: bool, duration_s: float, key: str, error: str | None) -> None:
        """A task finished (for good).

        Parameters
        ----------
        ok : bool
            Without error.
        duration_s : float
            Its run time, s.
        key : str
            Its key.
        error : str or None
            The error's first line when it failed.
        """
        self.n_new += 1
        if ok:
            self.n_done += 1
        else:
            self.n_failed += 1
            self._say(f"{self.label}: {key} failed: {error}")
        self._show(force=self.n_done + self.n_failed == self.total)

    def close(self, *, interrupted: bool, silent: bool = False) -> None:
        """End of the run.

        Parameters
        ----------
        interrupted : bool
            Ctrl-C stopped it.
        silent : bool
            No closing line (the run stopped on an error the caller reports).
        """
        if self.bar is not None:
            self.bar.stop()
            self.bar = None
        if self.enabled and not silent and (interrupted or not self.live):
            end = "interrupted; the finished runs are kept" if interrupted else "finished"
            self.stream.write(f"{self.label}: {end}: {self._counts(eta=False)}\n")
            self.stream.flush()

    # ----------------------------------------------------------------- output
    def eta_s(self) -> float | None:
        """Estimated time to finish from this run's rate, s (``None`` before the first task ends).

        Returns
        -------
        float or None
            Seconds.
        """
        if self.n_new == 0:
            return None
        left = self.total - self.n_done - self.n_failed
        return (time.monotonic() - self.t0) / self.n_new * left

    def _counts(self, eta: bool = True) -> str:
        text = (f"{self.n_done}/{self.total} done, {self.n_running} running, {self.n_failed} failed")
        return text + (f", ETA {format_eta(self.eta_s())}" if eta else "")

    def _say(self, line: str) -> None:
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.console.print(line, markup=False, highlight=False)
        else:
            self.stream.write(line + "\n")
            self.stream.flush()

    def _show(self, force: bool = False) -> None:
        if not self.enabled:
            return
        if self.bar is not None:
            self.bar.update(self.bar_id, completed=self.n_done + self.n_failed, counts=self._counts())
            return
        now = time.monotonic()
        if force or now - self.last_line >= PLAIN_EVERY_S:
            self.last_line = now
            self.stream.write(f"{self.label}: {self._counts()}\n")
            self.stream.flush()
