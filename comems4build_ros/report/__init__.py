"""Evaluation a researcher reads: paper-style figures, the findings and the comparison report.

``build.build_report(dir)`` builds ``report.md``/``report.html`` from the runs a
``comems4build compare`` wrote; ``runner`` executes runs in parallel processes;
``sweep`` tabulates and plots parameter grids. No rclpy import here.
"""
