"""Work on a stored run without the rig: identify again, plots and the HTML report."""
