"""Music-to-pose methods, one file each. Every method subclasses :class:`stage1_pose.models.base.Stage1Method`."""
