"""The ``segadeform`` command line: thin click commands over library calls."""
