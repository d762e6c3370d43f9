"""Running the many runs of a study: where they execute, what is stored, how a study resumes.

- :mod:`.spec`: a run's full specification and its hash, and the environment record (code,
  parameter files, library versions) every run's specification carries.
- :mod:`.store`: the resumable store of finished runs (``OUT/.runstore``).
- :mod:`.pool`: local worker processes or a Dask cluster; :func:`.pool.run_jobs`
  submits a study's runs, stores each as it finishes, resumes, shows progress.
- :mod:`.cluster`: a local Dask cluster of real ``dask scheduler`` / ``dask worker``
  processes (``bench study``, tests).

Nothing here imports rclpy or a node module.
"""
