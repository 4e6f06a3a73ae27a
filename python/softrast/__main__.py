"""``python -m softrast ...`` runs the console command (see softrast.cli)."""
from softrast.cli import main

raise SystemExit(main())
