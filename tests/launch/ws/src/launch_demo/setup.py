from glob import glob

from setuptools import setup

package_name = "launch_demo"
setup(
    name=package_name,
    version="0.0.1",
    packages=[package_name],
    data_files=[("share/ament_index/resource_index/packages", ["resource/" + package_name]),
                ("share/" + package_name, ["package.xml"]),
                ("share/" + package_name + "/launch", glob("launch/*.launch.py") + glob("launch/*.xml")),
                ("share/" + package_name + "/config", glob("config/*.yaml"))],
    install_requires=["setuptools"],
    entry_points={"console_scripts": ["talker = launch_demo.talker:main"]},
)
