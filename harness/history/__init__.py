"""A config measured at every commit of a range (`collide-bench history`): its command, the
commits measured, the series and their change points, the bisection that names a commit, and
the history page."""
