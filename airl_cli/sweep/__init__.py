"""``airl sweep``: an experiment of thesis chapter 7 as a resumable Hydra multirun, collected into one table.

Importing the package imports nothing: ``spec`` (file names, the ``airl.sweep`` resolver, the plan's
shape) sits below every module that runs a sweep, the launcher glue (``airl_cli.jobs.launch``) included.
"""
