"""A robot's recordings turned into demonstration datasets (`inest-import-demos`): ROS 2 bags,
LeRobot v3 datasets and folders of video files, each camera resampled to the dataset's rate."""
