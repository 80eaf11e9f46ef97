from setuptools import setup

package_name = "pacers"
setup(
    name=package_name,
    version="0.0.1",
    packages=[package_name],
    data_files=[("share/ament_index/resource_index/packages", ["resource/" + package_name]),
                ("share/" + package_name, ["package.xml"])],
    install_requires=["setuptools"],
    entry_points={"console_scripts": [
        "timer_node = pacers.timer_node:main",
        "spin_node = pacers.spin_node:main",
        "meddler = pacers.meddler:main",
        "chaser_node = pacers.chaser_node:main",
    ]},
)
