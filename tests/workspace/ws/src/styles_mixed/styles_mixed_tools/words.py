"""A module of the mixed package, installed with ament_python_install_package."""
WORD = "module"
