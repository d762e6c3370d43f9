"""ROS 2 launch file for a real Jazzy install: plant_sim, feed, one EMS and the recorder.

    ros2 launch comems4build_ros comems4build.launch.py ems:=fuzzy weeks:=12 bag:=/tmp/run/bag

Not tested here (launch_ros is not installable from PyPI); the tested path is the Python
launcher ``comems4build launch``, which also evaluates the bag (``comems4build evaluate
BAG --out DIR`` does that after this launch file). Arguments: ``ems`` (fuzzy, rbc, mpc),
``weeks`` (whole weeks, 0 = the scenario's default), ``steps`` (cut the run, 0 = all),
``scenario`` (``default`` or a CSV path), ``namespace`` (e.g. ``/building_0``), ``bag``
(bag directory to create). Set ROS_DOMAIN_ID yourself to isolate the run; the nodes
stop on their own except feed and EMS: end the launch with Ctrl-C once the recorder exits.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node

PACKAGE = "comems4build_ros"


def generate_launch_description() -> LaunchDescription:
    """The four nodes; the launch shuts down when the recorder has closed the bag."""
    ems = LaunchConfiguration("ems")
    ns = LaunchConfiguration("namespace")
    recorder = Node(
        package=PACKAGE,
        executable="recorder",
        name="recorder",
        parameters=[{"bag_path": LaunchConfiguration("bag"), "namespaces": [ns]}],
        output="screen",
    )
    return LaunchDescription(
        [
            DeclareLaunchArgument("ems", default_value="fuzzy", description="fuzzy, rbc or mpc"),
            DeclareLaunchArgument("weeks", default_value="0", description="run length [weeks], 0 = default"),
            DeclareLaunchArgument("steps", default_value="0", description="cut the run to N steps, 0 = all"),
            DeclareLaunchArgument("scenario", default_value="default", description="'default' or a CSV path"),
            DeclareLaunchArgument("namespace", default_value="/", description="namespace of the building"),
            DeclareLaunchArgument("bag", default_value="comems4build_bag", description="bag directory to create"),
            recorder,
            Node(
                package=PACKAGE,
                executable=PythonExpression(["'", ems, "' + '_ems'"]),
                namespace=ns,
                output="screen",
            ),
            Node(
                package=PACKAGE,
                executable="feed",
                namespace=ns,
                parameters=[
                    {
                        "scenario": LaunchConfiguration("scenario"),
                        "weeks": LaunchConfiguration("weeks"),
                        "steps": LaunchConfiguration("steps"),
                    }
                ],
                output="screen",
            ),
            Node(
                package=PACKAGE,
                executable="plant_sim",
                namespace=ns,
                parameters=[{"wait_for_recorder": True}],
                output="screen",
            ),
            RegisterEventHandler(OnProcessExit(target_action=recorder, on_exit=[EmitEvent(event=Shutdown())])),
        ]
    )
