"""Building membership gains a role: the plain many-to-many becomes the ``Membership``
through model on the same table, and each existing member gets the role of their group,
so nobody's access changes."""

from django.conf import settings
from django.db import migrations, models

GROUP_ROLES = {"admin": 3, "operator": 2, "viewer": 1}
ROLE_NAMES = {3: "admin", 2: "operator", 1: "viewer"}


def roles_from_groups(apps, schema_editor):
    Membership = apps.get_model("maps", "Membership")
    for membership in Membership.objects.filter(role="").select_related("user"):
        names = membership.user.groups.values_list("name", flat=True)
        rank = max((GROUP_ROLES.get(n, 0) for n in names), default=0)
        if rank:
            membership.role = ROLE_NAMES[rank]
            membership.save(update_fields=["role"])


class Migration(migrations.Migration):

    dependencies = [
        ("auth", "0012_alter_user_first_name_max_length"),
        migrations.swappable_dependency(settings.AUTH_USER_MODEL),
        ("maps", "0006_change_edits"),
    ]

    operations = [
        migrations.SeparateDatabaseAndState(
            state_operations=[
                migrations.CreateModel(
                    name="Membership",
                    fields=[
                        (
                            "id",
                            models.BigAutoField(
                                auto_created=True, primary_key=True, serialize=False, verbose_name="ID"
                            ),
                        ),
                        (
                            "building",
                            models.ForeignKey(
                                on_delete=models.deletion.CASCADE,
                                related_name="memberships",
                                to="maps.building",
                            ),
                        ),
                        (
                            "user",
                            models.ForeignKey(
                                on_delete=models.deletion.CASCADE,
                                related_name="memberships",
                                to=settings.AUTH_USER_MODEL,
                            ),
                        ),
                    ],
                    options={
                        "db_table": "maps_building_members",
                        "unique_together": {("building", "user")},
                    },
                ),
                migrations.AlterField(
                    model_name="building",
                    name="members",
                    field=models.ManyToManyField(
                        blank=True,
                        related_name="buildings",
                        through="maps.Membership",
                        to=settings.AUTH_USER_MODEL,
                    ),
                ),
            ],
            database_operations=[],
        ),
        migrations.AddField(
            model_name="membership",
            name="role",
            field=models.CharField(
                blank=True,
                choices=[("admin", "admin"), ("operator", "operator"), ("viewer", "viewer")],
                default="",
                max_length=10,
            ),
        ),
        migrations.RunPython(roles_from_groups, migrations.RunPython.noop),
    ]
