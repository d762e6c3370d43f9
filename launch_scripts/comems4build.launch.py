"""ROS 2 launch file of the node set: the run plan of ``comems4build launch``, started by ``ros2 launch``.

    ros2 launch comems4build_ros comems4build.launch.py ems:=rbc weeks:=1 out:=/tmp/run
    ros2 launch comems4build_ros comems4build.launch.py ems:=fuzzy houses:=4 namespace:=/site
    ros2 launch comems4build_ros comems4build.launch.py ems:=mpc weeks:=1 print_plan:=true

The arguments are those of ``comems4build launch`` (``ros2 launch comems4build_ros
comems4build.launch.py --show-args`` lists them): ``ems``, ``scenario``, ``start``,
``weeks``, ``steps``, ``houses``, ``seed``, ``namespace``, ``layout``, ``containers``,
``config``/``set``/``ems_options`` (``;``-separated), ``forecast``, ``all_inputs``, ``step_timeout``,
``timeout``, ``out``, ``bag``, ``domain`` and ``print_plan``. Both build the same run plan
(:mod:`comems4build_ros.app.ros2_launch`), start the same nodes with the same parameters
and end by the same rule: the run ends once every recorder has closed its bag, and ``ros2
launch`` exits non-zero when a node fails or the time limit passes. Evaluate the bag
with ``comems4build evaluate <out>/bag --out <out>``.

Inside a launch of one's own the file may be included any number of times, each inclusion
in a namespace of its own (``PushRosNamespace`` in a ``GroupAction``, or ``namespace:=``):
each is a run of its own that ends its own processes only, and ``ros2 launch`` exits 1 if
any of them was cut short (docs/ros_tools.md "ROS 2 launch file").
"""

from comems4build_ros.app.ros2_launch import launch_description


def generate_launch_description():  # noqa: ANN201 (the launch API's entry point)
    """The launch description: the declared arguments and the plan they give."""
    return launch_description()
