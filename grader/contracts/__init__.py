"""The ground floor: values and contracts every other package shares, defined once.

Nothing here imports another grader package, so any package may import it (the rubric model,
the scenario model, the analyzers, the reports) without an arrow running back up the floors.
Each module is small and light: ``world`` and ``status`` are plain constants (the wheel build,
which has only PyYAML and pydantic, reads rubrics through them); ``jsonable`` needs numpy and
pandas and is imported only by the packages that already use them.
"""
