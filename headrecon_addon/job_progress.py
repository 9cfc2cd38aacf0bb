"""How a background job (Fit, Detect Landmarks) reports its progress and is stopped: no
bpy, so it runs in any thread (``job_operator.py`` runs the jobs)."""


class JobCancelled(Exception):
    """Raised from a job's progress report to stop a job the artist cancelled."""


class Progress:
    """Mixin of a job with ``cancelled``, ``fraction`` and ``message`` attributes."""

    def progress(self, fraction, message):
        """Record how far the job is; once cancelled, stop it (``JobCancelled``)."""
        if self.cancelled:
            raise JobCancelled()
        self.fraction = float(fraction)
        self.message = str(message)
