from setuptools import setup

package_name = "turtle_goal"
setup(
    name=package_name,
    version="0.0.1",
    packages=[package_name],
    data_files=[("share/ament_index/resource_index/packages", ["resource/" + package_name]),
                ("share/" + package_name, ["package.xml"])],
    entry_points={"console_scripts": ["hello = turtle_goal.hello:main"]},
)
