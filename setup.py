"""Package discovery; the metadata is in pyproject.toml.

Every package under strokekit/ is found (a new stage cannot be left out of the wheel), and the
click front end in cli/ is installed as `strokekit_cli`, a name of the project's own.
"""

from setuptools import find_packages, setup

CLI = ["strokekit_cli"] + [f"strokekit_cli.{name}" for name in find_packages("cli")]

setup(packages=find_packages(include=["strokekit", "strokekit.*"]) + CLI, package_dir={"strokekit_cli": "cli"})
