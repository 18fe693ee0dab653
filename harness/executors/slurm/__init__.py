"""Slurm as an executor: each pending cell one task of a Slurm job array (executor), through
Slurm's client commands and with the jobs in flight on file (client)."""
