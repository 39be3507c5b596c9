"""Install hair_sim (ament_python package)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'hair_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/heads',
         glob('config/heads/*.yaml') + glob('config/heads/*.glb')),
        ('share/' + package_name + '/config/hairstyles', glob('config/hairstyles/*.yaml')),
        ('share/' + package_name + '/launch', glob('config/launch/*.launch.xml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='hair_sim developers',
    maintainer_email='hair-sim-dev@example.com',
    description='Real-time strip-based hair simulation with U-shape volume for ROS 2.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'hair_sim_node = hair_sim.ros.node:main',
            'hair_sim_demo = hair_sim.ros.demo:main',
            'hair_sim_head_driver = hair_sim.ros.head_driver:main',
            'hair_sim_bench = hair_sim.bench.cli:main',
            'hair_sim_head = hair_sim.modeling.head_tool:main',
        ],
    },
)
