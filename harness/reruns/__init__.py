"""Reruns of configs measured apart (`collide-bench reruns`): its command, and what they say
of a machine's session spread and of how often an interval holds another rerun's estimate."""
